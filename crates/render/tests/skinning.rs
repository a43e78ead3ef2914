//! The GPU skinning pass (`shaders/skinning.wgsl`, [`SkinningPass`]) against the CPU reference
//! `furbake_runtime::animation::morph_and_skin` (glTF 2.0 "Morph Targets", "Skins"), read back
//! on whatever adapter the machine has (Mesa lavapipe without a GPU; like the other render tests
//! these never skip: without an adapter they fail with the command that installs lavapipe).
//!
//! Cases: the bundled Fox playing "Survey", "Walk" and "Run" at several times; synthetic meshes
//! with eight influences, mirrored and non-uniformly scaled joints and three morph targets (with
//! and without normal deltas, one at weight 0), morph-only and skin-only; a joint scaled to zero
//! (its vertices collapse, normals fall back to the bind normal, nothing is NaN); typed errors for
//! bad poses; and a baked Fox drawn by a [`FurRenderer`], whose shells grow from the skinned
//! vertices with scale vectors given in the posed frame (the `shell_positions` probe
//! against the CPU, per vertex at rest and per corner tilted) and whose posed frame differs from
//! the bind pose.
//!
//! Tolerances, and why: the GPU evaluates the reference's f32 formula in the same order, so the
//! only differences are fused multiply-adds and the driver's `length`/division (Vulkan allows a
//! few ulps each). Positions go through at most ~30 roundings of values no larger than the mesh's
//! extent, so they must agree within [`POSITION_TOLERANCE`] × the bounding-box diagonal (≈ 80
//! ulps of the largest coordinate); unit normals within [`NORMAL_TOLERANCE_RAD`]. Both are far
//! below a shell texel and far above the measured error, printed by each test.

use std::path::Path;
use std::sync::OnceLock;

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::SectionKind;
use furbake_formats::sections::morph_targets::{MorphGroup, MorphTargets};
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_import::{ImportSettings, ImportedMesh, import_gltf};
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::testing::SkinningPass;
use furbake_render::{FurAsset, FurGpuAsset, FurRenderer, RenderError, RenderSettings, View};
use furbake_runtime::Pack;
use furbake_runtime::ShellVertexLayout;
use furbake_runtime::animation::{AnimationPlayer, Pose, joint_world_matrices, morph_and_skin, skinning_matrices};
use glam::{Mat4, Quat, Vec3};

/// Largest position error allowed, relative to the skin's bounding-box diagonal.
const POSITION_TOLERANCE: f64 = 1e-5;
/// Largest angle allowed between the GPU's and the CPU's unit normal, radians.
const NORMAL_TOLERANCE_RAD: f64 = 1e-3;

fn fox_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb")
}

/// The bundled Fox, imported (skeleton, skin weights, clips).
fn fox() -> &'static ImportedMesh {
    static FOX: OnceLock<ImportedMesh> = OnceLock::new();
    FOX.get_or_init(|| import_gltf(&fox_path(), &ImportSettings::default()).unwrap())
}

/// The skinning matrices and morph weights of `mesh` playing `clip` at `time_s`, through the
/// runtime's player (sampling, then `world(joint) × inverseBind`).
fn pose_of(mesh: &ImportedMesh, clip: &str, time_s: f32, edit: impl FnOnce(&mut Pose)) -> (Vec<Mat4>, Vec<f32>) {
    let a = &mesh.animation;
    let (skeleton, morphs, clips) = (a.skeleton.as_ref().unwrap(), a.morph_targets.as_ref(), a.clips.as_ref().unwrap());
    let mut player = AnimationPlayer::new(clips, clip, 1.0, true, Some(skeleton), morphs).unwrap();
    player.seek(clips, time_s);
    let mut pose = Pose::rest(Some(skeleton), morphs);
    let groups = morphs.map_or(&[][..], |m| &m.groups[..]);
    player.pose(clips, groups, &mut pose).unwrap();
    edit(&mut pose);
    let mut world = vec![Mat4::IDENTITY; skeleton.joint_count()];
    let mut palette = vec![Mat4::IDENTITY; skeleton.bind_count()];
    joint_world_matrices(skeleton, &pose, &mut world).unwrap();
    skinning_matrices(skeleton, &world, &mut palette).unwrap();
    (palette, pose.morph_weights)
}

type Posed = Vec<([f32; 3], [f32; 3])>;

/// The CPU reference.
fn cpu_skin(
    mesh: &SkinMesh,
    weights: Option<&SkinWeights>,
    morphs: Option<&MorphTargets>,
    palette: &[Mat4],
    morph_weights: &[f32],
) -> Posed {
    let v = mesh.positions.len();
    let (mut p, mut n) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v]);
    morph_and_skin(mesh, weights, morphs.map(|m| (m, morph_weights)), palette, &mut p, &mut n).unwrap();
    p.into_iter().zip(n).collect()
}

/// One GPU dispatch with this pose, read back.
fn gpu_skin(pass: &SkinningPass, palette: &[Mat4], morph_weights: &[f32]) -> Posed {
    let g = gpu();
    pass.set_pose(&g.queue, palette, morph_weights).unwrap();
    let mut encoder = g.device.create_command_encoder(&Default::default());
    pass.encode(&mut encoder);
    g.queue.submit([encoder.finish()]);
    let out = pass.read_back(&g.device, &g.queue).unwrap();
    g.check().unwrap();
    out.positions.into_iter().zip(out.normals).collect()
}

/// Worst errors of one comparison.
#[derive(Debug, Default, Clone, Copy)]
struct Errors {
    vertices: usize,
    position_over_diagonal: f64,
    normal_rad: f64,
}

impl Errors {
    fn max(self, o: Errors) -> Errors {
        Errors {
            vertices: self.vertices + o.vertices,
            position_over_diagonal: self.position_over_diagonal.max(o.position_over_diagonal),
            normal_rad: self.normal_rad.max(o.normal_rad),
        }
    }
}

fn diagonal(mesh: &SkinMesh) -> f64 {
    let (lo, hi) = mesh.bounds();
    Vec3::from(hi).as_dvec3().distance(Vec3::from(lo).as_dvec3())
}

/// Compares GPU with CPU vertex by vertex, asserting the tolerances; `what` names the case.
fn compare(what: &str, cpu: &Posed, gpu: &Posed, diagonal: f64) -> Errors {
    assert_eq!(cpu.len(), gpu.len(), "{what}: vertex counts");
    let mut e = Errors::default();
    for (v, ((cp, cn), (gp, gn))) in cpu.iter().zip(gpu).enumerate() {
        let (cp, gp) = (Vec3::from(*cp).as_dvec3(), Vec3::from(*gp).as_dvec3());
        let (cn, gn) = (Vec3::from(*cn).as_dvec3(), Vec3::from(*gn).as_dvec3());
        assert!(gp.is_finite() && gn.is_finite(), "{what}: vertex {v} is not finite: {gp} {gn}");
        let dp = cp.distance(gp) / diagonal;
        // atan2(|a × b|, a·b): accurate for small angles, unlike acos of the dot product.
        let angle = cn.cross(gn).length().atan2(cn.dot(gn));
        assert!(
            dp <= POSITION_TOLERANCE,
            "{what}: vertex {v} position GPU {gp} vs CPU {cp}: {dp:e} × diagonal > {POSITION_TOLERANCE:e}"
        );
        assert!(
            angle <= NORMAL_TOLERANCE_RAD,
            "{what}: vertex {v} normal GPU {gn} vs CPU {cn}: {angle:e} rad > {NORMAL_TOLERANCE_RAD:e}"
        );
        e.vertices += 1;
        e.position_over_diagonal = e.position_over_diagonal.max(dp);
        e.normal_rad = e.normal_rad.max(angle);
    }
    e
}

#[test]
fn the_fox_skinned_on_the_gpu_matches_the_cpu_reference() {
    let fox = fox();
    let a = &fox.animation;
    let weights = a.skin_weights.as_ref().expect("the Fox is skinned");
    let pass = SkinningPass::new(&gpu().device, &fox.mesh, Some(weights), a.morph_targets.as_ref()).unwrap();
    assert_eq!(pass.vertex_count() as usize, fox.mesh.positions.len());
    assert_eq!(pass.bind_count(), weights.bind_count);
    let diagonal = diagonal(&fox.mesh);
    let mut total = Errors::default();
    let (mut cases, mut moved) = (0, 0);
    for clip in ["Survey", "Walk", "Run"] {
        for time_s in [0.0, 0.41, 1.37] {
            let (palette, morph_weights) = pose_of(fox, clip, time_s, |_| {});
            let cpu = cpu_skin(&fox.mesh, Some(weights), a.morph_targets.as_ref(), &palette, &morph_weights);
            let gpu = gpu_skin(&pass, &palette, &morph_weights);
            let far = |(p, b): (&([f32; 3], [f32; 3]), &[f32; 3])| {
                Vec3::from(p.0).as_dvec3().distance(Vec3::from(*b).as_dvec3()) > 1e-3 * diagonal
            };
            moved += cpu.iter().zip(&fox.mesh.positions).filter(|&x| far(x)).count();
            total = total.max(compare(&format!("{clip} at {time_s} s"), &cpu, &gpu, diagonal));
            cases += 1;
        }
    }
    // The poses really move the skin (else the comparison would prove little).
    assert!(moved * 3 > total.vertices, "only {moved} of {} posed vertices left the bind pose", total.vertices);
    println!(
        "Fox: {} vertices, {cases} poses, {} vertex comparisons; worst position error {:.2e} × diagonal \
         ({:.3e} m of {diagonal:.3} m), worst normal error {:.2e} rad",
        fox.mesh.positions.len(),
        total.vertices,
        total.position_over_diagonal,
        total.position_over_diagonal * diagonal,
        total.normal_rad
    );
    assert_eq!(total.vertices, 9 * fox.mesh.positions.len());
}

/// A deterministic generator (64-bit LCG), so the synthetic cases are the same on every run.
struct Lcg(u64);

impl Lcg {
    /// Uniform in [-1, 1).
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next())
    }

    fn unit(&mut self) -> Vec3 {
        loop {
            let v = self.vec3();
            if v.length() > 0.1 && v.length() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// `vertices` random points in a 2 m cube with random unit normals (no triangles: the pass
/// skins vertices).
fn random_mesh(rng: &mut Lcg, vertices: usize) -> SkinMesh {
    SkinMesh {
        positions: (0..vertices).map(|_| rng.vec3().to_array()).collect(),
        normals: (0..vertices).map(|_| rng.unit().to_array()).collect(),
        ..Default::default()
    }
}

/// `k` influences per vertex on `binds` binds, random weights normalised to 1, some slots 0.
fn random_weights(rng: &mut Lcg, vertices: usize, k: u32, binds: u32) -> SkinWeights {
    let mut out = SkinWeights { influences_per_vertex: k, bind_count: binds, ..Default::default() };
    for _ in 0..vertices {
        let w: Vec<f32> =
            (0..k).map(|s| if s > 0 && rng.next() < -0.5 { 0.0 } else { rng.next().abs() + 0.05 }).collect();
        let sum: f32 = w.iter().sum();
        for x in w {
            out.binds.push(((rng.next() * 0.5 + 0.5) * binds as f32).min(binds as f32 - 1.0) as u16);
            out.weights.push(x / sum);
        }
    }
    out
}

/// `targets` morph targets in one group, deltas up to 0.3 m, normal deltas unless `positions_only`.
fn random_morphs(rng: &mut Lcg, vertices: usize, targets: usize, positions_only: bool) -> MorphTargets {
    let deltas = |rng: &mut Lcg| (0..targets * vertices).map(|_| (rng.vec3() * 0.3).to_array()).collect::<Vec<_>>();
    let position_deltas = deltas(rng);
    let normal_deltas = if positions_only { Vec::new() } else { deltas(rng) };
    MorphTargets {
        vertex_count: vertices as u32,
        names: (0..targets).map(|t| format!("t{t}")).collect(),
        groups: vec![MorphGroup { name: "g".into(), first_target: 0, target_count: targets as u32 }],
        position_deltas,
        normal_deltas,
        default_weights: vec![0.0; targets],
    }
}

/// Five skinning matrices covering the cases of the normal rule: a rotation with translation, a
/// non-uniform scale, a mirror (negative determinant), a general affine map (shear), identity.
fn palette() -> Vec<Mat4> {
    let rot = Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 0.9);
    vec![
        Mat4::from_rotation_translation(rot, Vec3::new(0.3, -1.2, 2.0)),
        Mat4::from_scale_rotation_translation(Vec3::new(2.0, 0.5, 1.3), rot.inverse(), Vec3::new(-0.5, 0.1, 0.0)),
        Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)) * Mat4::from_rotation_y(0.4),
        Mat4::from_cols_array(&[1.0, 0.2, -0.1, 0.0, 0.3, 0.9, 0.25, 0.0, -0.2, 0.1, 1.1, 0.0, 0.5, 0.5, -0.5, 1.0]),
        Mat4::IDENTITY,
    ]
}

#[test]
fn morph_targets_and_eight_influences_match_the_cpu_reference() {
    let g = gpu();
    let mut rng = Lcg(11);
    let v = 1000;
    let mesh = random_mesh(&mut rng, v);
    let diagonal = diagonal(&mesh);
    let matrices = palette();
    let eight = random_weights(&mut rng, v, 8, matrices.len() as u32);
    let four = random_weights(&mut rng, v, 4, matrices.len() as u32);
    let morphs = random_morphs(&mut rng, v, 3, false);
    let position_morphs = random_morphs(&mut rng, v, 2, true);
    // One weight 0 (skipped, as on the CPU), one negative.
    let (w3, w2) = ([0.7, 0.0, -0.4], [0.25, 1.0]);
    // (what, weights, morph targets, with the matrices, with the morph weights)
    type Case<'a> = (&'a str, Option<&'a SkinWeights>, Option<&'a MorphTargets>, bool, &'a [f32]);
    let cases: [Case<'_>; 5] = [
        ("8 influences + 3 morph targets", Some(&eight), Some(&morphs), true, &w3),
        ("4 influences + position-only morphs", Some(&four), Some(&position_morphs), true, &w2),
        ("morph targets only", None, Some(&morphs), false, &w3),
        ("8 influences only", Some(&eight), None, true, &[]),
        ("4 influences only", Some(&four), None, true, &[]),
    ];
    let mut total = Errors::default();
    for (what, weights, morphs, skinned, morph_weights) in cases {
        let matrices = if skinned { &matrices[..] } else { &[] };
        let pass = SkinningPass::new(&g.device, &mesh, weights, morphs).unwrap();
        let cpu = cpu_skin(&mesh, weights, morphs, matrices, morph_weights);
        let gpu = gpu_skin(&pass, matrices, morph_weights);
        let e = compare(what, &cpu, &gpu, diagonal);
        println!(
            "{what}: worst position {:.2e} × diagonal, worst normal {:.2e} rad",
            e.position_over_diagonal, e.normal_rad
        );
        total = total.max(e);
    }
    assert_eq!(total.vertices, 5 * v);
    // The mirrored bind really flips the cofactor's sign somewhere (the sign(det) path ran).
    let mirrored = (0..v).filter(|&i| four.influences(i).any(|(b, w)| b == 2 && w > 0.5)).count();
    assert!(mirrored > 10, "only {mirrored} vertices mostly bound to the mirror");
}

#[test]
fn a_joint_scaled_to_zero_collapses_its_vertices_and_keeps_their_bind_normals() {
    // The cofactor of a zero 3×3 block is zero, so the skinned normal collapses; the rule (CPU
    // and GPU) keeps the bind normal instead of normalising a zero vector into NaN.
    let g = gpu();
    let mut rng = Lcg(5);
    let v = 300;
    let mesh = random_mesh(&mut rng, v);
    let tip = Vec3::new(0.25, 1.5, -0.75);
    let matrices = [Mat4::from_scale_rotation_translation(Vec3::ZERO, Quat::from_rotation_z(0.3), tip), palette()[1]];
    // Vertex i: fully on the zero-scaled bind (i % 3 = 0), half and half, or on the other bind.
    let mut weights = SkinWeights { influences_per_vertex: 4, bind_count: 2, ..Default::default() };
    for i in 0..v {
        let w0 = [1.0, 0.5, 0.0][i % 3];
        weights.binds.extend_from_slice(&[0, 1, 0, 0]);
        weights.weights.extend_from_slice(&[w0, 1.0 - w0, 0.0, 0.0]);
    }
    let pass = SkinningPass::new(&g.device, &mesh, Some(&weights), None).unwrap();
    let cpu = cpu_skin(&mesh, Some(&weights), None, &matrices, &[]);
    let gpu = gpu_skin(&pass, &matrices, &[]);
    let e = compare("a joint scaled to zero", &cpu, &gpu, diagonal(&mesh));
    let mut collapsed = 0;
    for (i, (p, n)) in gpu.iter().enumerate().filter(|(i, _)| i % 3 == 0) {
        assert!(Vec3::from(*p).distance(tip) < 1e-6, "vertex {i} did not collapse onto the joint: {p:?}");
        assert_eq!(*n, mesh.normals[i], "vertex {i} does not keep its bind normal");
        collapsed += 1;
    }
    assert_eq!(collapsed, v.div_ceil(3));
    assert_eq!(e.vertices, v);

    // The same on the Fox: the joint whose bind carries the most rigidly bound vertices is scaled
    // to zero mid-walk.
    let fox = fox();
    let a = &fox.animation;
    let (skeleton, fox_weights) = (a.skeleton.as_ref().unwrap(), a.skin_weights.as_ref().unwrap());
    let mut rigid = vec![0usize; skeleton.bind_count()];
    for i in 0..fox.mesh.positions.len() {
        if let Some((b, _)) = fox_weights.influences(i).find(|&(_, w)| w >= 0.999) {
            rigid[b as usize] += 1;
        }
    }
    let bind = (0..rigid.len()).max_by_key(|&b| rigid[b]).unwrap();
    let joint = skeleton.bind_joints[bind] as usize;
    let (palette, morph_weights) = pose_of(fox, "Walk", 0.5, |pose| pose.scales[joint] = Vec3::ZERO);
    let pass = SkinningPass::new(&g.device, &fox.mesh, Some(fox_weights), None).unwrap();
    let cpu = cpu_skin(&fox.mesh, Some(fox_weights), None, &palette, &morph_weights);
    let gpu = gpu_skin(&pass, &palette, &morph_weights);
    let e = compare("Fox with a joint scaled to zero", &cpu, &gpu, diagonal(&fox.mesh));
    let kept = gpu.iter().zip(&fox.mesh.normals).filter(|((_, n), b)| n == *b).count();
    println!(
        "zero-scaled joint {joint} ({:?}): {} rigid vertices, {kept} keep their bind normal; worst {:.2e} × diagonal, {:.2e} rad",
        skeleton.names[joint], rigid[bind], e.position_over_diagonal, e.normal_rad
    );
    assert!(kept >= rigid[bind] && rigid[bind] > 0, "{kept} bind normals kept, {} rigid vertices", rigid[bind]);
}

#[test]
fn bad_poses_and_sections_are_typed_errors() {
    let g = gpu();
    let fox = fox();
    let weights = fox.animation.skin_weights.as_ref().unwrap();
    let pass = SkinningPass::new(&g.device, &fox.mesh, Some(weights), None).unwrap();
    let n = weights.bind_count as usize;
    let parameter = |r: Result<(), RenderError>| matches!(r, Err(RenderError::Parameter { .. }));
    assert!(parameter(pass.set_pose(&g.queue, &vec![Mat4::IDENTITY; n - 1], &[])), "too few matrices");
    assert!(parameter(pass.set_pose(&g.queue, &vec![Mat4::IDENTITY; n], &[0.5])), "weights without targets");
    let mut nan = vec![Mat4::IDENTITY; n];
    nan[n / 2].w_axis.x = f32::NAN;
    assert!(parameter(pass.set_pose(&g.queue, &nan, &[])), "a NaN matrix");
    pass.set_pose(&g.queue, &vec![Mat4::IDENTITY; n], &[]).unwrap();

    let mut rng = Lcg(3);
    let mesh = random_mesh(&mut rng, 10);
    let morphs = random_morphs(&mut rng, 10, 2, false);
    let morph_pass = SkinningPass::new(&g.device, &mesh, None, Some(&morphs)).unwrap();
    assert!(parameter(morph_pass.set_pose(&g.queue, &[], &[1.0, f32::INFINITY])), "an infinite weight");
    assert!(parameter(morph_pass.set_pose(&g.queue, &[Mat4::IDENTITY], &[1.0, 0.0])), "matrices without skin");

    // Sections that do not belong to the mesh, or nothing to skin.
    let short = random_morphs(&mut rng, 9, 2, false);
    let err = SkinningPass::new(&g.device, &mesh, None, Some(&short)).err().unwrap();
    assert!(matches!(err, RenderError::InvalidAsset { .. }), "{err}");
    let mut out_of_range = random_weights(&mut rng, 10, 4, 2);
    out_of_range.binds[7] = 2;
    let err = SkinningPass::new(&g.device, &mesh, Some(&out_of_range), None).err().unwrap();
    assert!(matches!(err, RenderError::InvalidAsset { .. }), "{err}");
    let err = SkinningPass::new(&g.device, &mesh, None, None).err().unwrap();
    assert!(matches!(err, RenderError::Parameter { .. }), "{err}");
    g.check().unwrap();
}

/// The Fox baked (16 layers of 32² shells) into a pack, and that pack opened.
fn fox_pack() -> &'static (tempfile::TempDir, Pack) {
    static PACK: OnceLock<(tempfile::TempDir, Pack)> = OnceLock::new();
    PACK.get_or_init(|| {
        let mut settings = BakeSettings::preset("fur").unwrap();
        settings.volume.layers = 16;
        settings.volume.resolution = 32;
        let baked = bake(fox(), "fox", &settings.plan().unwrap(), &mut NoProgress).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fox.fbk");
        baked.to_writer().write_atomic(&path).unwrap();
        let pack = Pack::open(&path).unwrap();
        (dir, pack)
    })
}

#[test]
fn the_fur_renderer_grows_every_shell_from_the_skinned_vertices() {
    let g = gpu();
    let pack = &fox_pack().1;
    let asset = FurAsset::from_pack(pack, true).unwrap();
    assert!(asset.is_animated() && asset.skin_weights().is_some());
    assert!(pack.kinds_read().contains(&SectionKind::SKIN_WEIGHTS));
    assert!(!pack.kinds_read().contains(&SectionKind::ANIMATION_CLIPS), "the renderer never reads clips");
    let settings = RenderSettings { shell_layers: Some(4), ..Default::default() };
    let renderer = FurRenderer::new(g.pipelines(), &g.queue, &asset, &settings, &RenderTarget::desc()).unwrap();
    let skinning = renderer.skinning().expect("an animated asset has a skinning pass");
    assert_eq!(skinning.vertex_count() as usize, asset.mesh().positions.len());

    let (palette, morph_weights) = pose_of(fox(), "Run", 0.3, |_| {});
    renderer.set_pose(&g.queue, &palette, &morph_weights).unwrap();
    let mesh = asset.mesh();
    let cpu = cpu_skin(mesh, asset.skin_weights(), asset.morph_targets(), &palette, &morph_weights);
    let (v, layers) = (mesh.positions.len(), renderer.drawn_layers());
    let (length, k) = (asset.shells().fur_length_m, settings.shear_exponent);
    let diagonal = diagonal(mesh);
    // The skinned root's tolerance, plus the normal's and the scale vector's angles over the
    // shell's height and shear (≤ 2 fur lengths each), plus the driver's pow on t^k (physics.rs).
    let tolerance = POSITION_TOLERANCE
        + (4.0 * NORMAL_TOLERANCE_RAD + f64::from(k) * 2f64.powi(-20) * 2.0) * f64::from(length) / diagonal;
    // Scale vectors in the posed mesh frame (the runtime poses the physics on the skinned
    // surface), per welded vertex or per triangle corner: the rest pose (s = posed normal) and
    // every s tilted about 30° off its normal.
    let posed_normal = |i: usize| Vec3::from(cpu[i].1).normalize();
    let tilted = |i: usize| {
        let n = posed_normal(i);
        (n + 0.6 * n.cross(Vec3::X).try_normalize().unwrap_or(Vec3::Z)).normalize()
    };
    let per_vertex: Vec<u32> = (0..v as u32).collect();
    let per_corner: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let layouts = [
        ("rest, per vertex", ShellVertexLayout::PerVertex, &per_vertex, false),
        ("tilted, per corner", ShellVertexLayout::PerCorner, &per_corner, true),
    ];
    let mut checked = 0;
    for (what, layout, welded, tilt) in layouts {
        let posed_s: Vec<Vec3> =
            welded.iter().map(|&i| if tilt { tilted(i as usize) } else { posed_normal(i as usize) }).collect();
        let raw: Vec<[f32; 3]> = posed_s.iter().map(|s| s.to_array()).collect();
        renderer.set_shell_scale_vectors(&g.queue, &raw, layout).unwrap();
        let shells = renderer.shell_positions(&g.device, &g.queue, &asset).unwrap();
        assert_eq!(shells.len(), welded.len() * layers as usize, "{what}");
        let mut worst = 0.0f64;
        for layer in 0..layers {
            for (c, &i) in welded.iter().enumerate() {
                let (p, n) = (Vec3::from(cpu[i as usize].0), Vec3::from(cpu[i as usize].1));
                let s = posed_s[c];
                let expected = furbake_sim::shell_vertex_position(p, n, s, layer + 1, layers, length, k).as_dvec3();
                let got = Vec3::from(shells[layer as usize * welded.len() + c]).as_dvec3();
                let err = got.distance(expected) / diagonal;
                assert!(err <= tolerance, "{what}, layer {layer}, shell vertex {c}: GPU {got} vs CPU {expected}");
                worst = worst.max(err);
                checked += 1;
            }
        }
        println!("posed shells, {what}: {} positions, worst error {worst:.2e} × diagonal", shells.len());
    }
    assert_eq!(checked, (v + per_corner.len()) * layers as usize);
    renderer.set_scale_vectors(&g.queue, &mesh.normals).unwrap();

    // The frame: bind pose and posed differ, both drawn (the fins' posed face normals, the skin
    // and the shells all compile and run with SKINNED).
    let target = RenderTarget::new(&g.device, 128, 128).unwrap();
    let view = View::framing(asset.bounding_sphere().0, asset.bounding_sphere().1 * 1.3);
    let draw = |palette: &[Mat4]| {
        renderer.set_pose(&g.queue, palette, &morph_weights).unwrap();
        renderer.render_to(&g.device, &g.queue, &target, &view).unwrap();
        read_back(&g.device, &g.queue, &target).unwrap()
    };
    let bind_pose = draw(&vec![Mat4::IDENTITY; palette.len()]);
    let running = draw(&palette);
    g.check().unwrap();
    let bg = bind_pose.get_pixel(0, 0).0;
    let drawn = |img: &image::RgbaImage| img.pixels().filter(|p| p.0 != bg).count();
    let changed = bind_pose.pixels().zip(running.pixels()).filter(|(a, b)| a != b).count();
    println!("bind pose {} px, running {} px, {changed} px changed", drawn(&bind_pose), drawn(&running));
    assert!(drawn(&bind_pose) > 1000 && drawn(&running) > 1000);
    assert!(changed > 200, "the pose changed only {changed} pixels");
    running.save(std::env::temp_dir().join("furbake_fox_running.png")).unwrap();

    // A static asset has no pass and refuses a pose.
    let fins = Some((pack.fin_atlas().unwrap(), pack.fin_edges().unwrap()));
    let still =
        FurAsset::new(pack.skin_mesh().unwrap(), pack.shell_atlas().unwrap(), pack.triangle_uv_map().unwrap(), fins)
            .unwrap();
    assert!(!still.is_animated());
    let static_renderer = FurRenderer::new(g.pipelines(), &g.queue, &still, &settings, &RenderTarget::desc()).unwrap();
    assert!(static_renderer.skinning().is_none());
    let err = static_renderer.set_pose(&g.queue, &palette, &morph_weights).unwrap_err();
    assert!(matches!(err, RenderError::Parameter { .. }), "{err}");
    assert!(asset.gpu_bytes(true) > still.gpu_bytes(true) + 64 * mesh.positions.len() as u64);
}

/// Milliseconds per frame of `frames` frames that each write a pose from `poses`, record the
/// dispatch (or nothing, when not `dispatch`), submit alone and wait for the GPU.
fn frame_ms(pass: &SkinningPass, poses: &[(Vec<Mat4>, Vec<f32>)], frames: usize, dispatch: bool) -> f64 {
    let g = gpu();
    let start = std::time::Instant::now();
    for f in 0..frames {
        let (palette, weights) = &poses[f % poses.len()];
        pass.set_pose(&g.queue, palette, weights).unwrap();
        let mut encoder = g.device.create_command_encoder(&Default::default());
        if dispatch {
            pass.encode(&mut encoder);
        }
        g.queue.submit([encoder.finish()]);
        g.device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    }
    start.elapsed().as_secs_f64() * 1e3 / frames as f64
}

/// Time of the skinning pass on this machine's adapter: the Fox playing "Run", and a synthetic
/// 100,000-vertex skin with 8 influences and 4 morph targets for scale; `FRAMES` frames each
/// (default 300), each dispatch submitted alone and waited for, against the same loop
/// submitting an empty command buffer. Run with
/// `cargo test -p furbake-render --test render -- --ignored --nocapture skinning_pass_time`.
// Ignored in `make test` on purpose: it asserts nothing (speed belongs in measurements quoted in
// docs/performance.md, not in timed tests), and its 600 waited-for dispatches of a 100,000-vertex
// skin take tens of seconds on lavapipe. It shares this file's fixtures and CPU reference, so it
// lives here rather than in an example.
#[test]
#[ignore = "a measurement, not a check"]
fn skinning_pass_time() {
    let g = gpu();
    let frames: usize = std::env::var("FRAMES").ok().and_then(|s| s.parse().ok()).unwrap_or(300);
    println!("adapter {} ({:?}), {frames} frames per row", g.info.name, g.info.backend);
    println!("| skin | vertices | pass + submit + wait (ms) | empty submit + wait (ms) | pass (ms) |");
    println!("|---|---:|---:|---:|---:|");
    let fox = fox();
    let a = &fox.animation;
    let fox_pass = SkinningPass::new(&g.device, &fox.mesh, a.skin_weights.as_ref(), a.morph_targets.as_ref()).unwrap();
    let fox_poses: Vec<_> = (0..30).map(|i| pose_of(fox, "Run", i as f32 * 0.023, |_| {})).collect();
    let mut rng = Lcg(7);
    let v = 100_000;
    let mesh = random_mesh(&mut rng, v);
    let (weights, morphs) = (random_weights(&mut rng, v, 8, 5), random_morphs(&mut rng, v, 4, false));
    let big_pass = SkinningPass::new(&g.device, &mesh, Some(&weights), Some(&morphs)).unwrap();
    let big_poses = vec![(palette(), vec![0.5, 0.0, 0.25, 1.0])];
    let rows = [
        (
            format!("Fox \"Run\", {} influences/vertex", a.skin_weights.as_ref().unwrap().influences_per_vertex),
            &fox_pass,
            &fox_poses,
        ),
        ("synthetic, 8 influences + 4 morph targets".to_string(), &big_pass, &big_poses),
    ];
    for (what, pass, poses) in rows {
        frame_ms(pass, poses, 10, true); // warm up: pipeline compilation, first allocations
        let (with, without) = (frame_ms(pass, poses, frames, true), frame_ms(pass, poses, frames, false));
        println!("| {what} | {} | {with:.3} | {without:.3} | {:.3} |", pass.vertex_count(), with - without);
    }
}

/// End to end: a runtime `World` playing the Run clip, drawn by a `SceneRenderer` — the skinning
/// pass's posed vertices after `render_world` are the world's CPU `Animator` positions, and the
/// frame differs from the same world in its bind pose.
#[test]
fn a_world_playing_a_clip_is_drawn_in_the_worlds_pose() {
    use furbake_render::SceneRenderer;
    use furbake_render::headless::RenderTarget;
    use furbake_runtime::{Scene, World};
    let g = gpu();
    let dir = fox_pack().0.path();
    let world_with = |animation: &str| {
        let text = format!("time_step_s = 0.01\n[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\n{animation}\n");
        World::new(Scene::from_toml_str(&text, Path::new("t.toml"), dir).unwrap()).unwrap()
    };
    let target = RenderTarget::new(&g.device, 96, 96).unwrap();
    let draw = |world: &World| {
        let renderer = SceneRenderer::new(&g.device, &g.queue, world).unwrap();
        renderer.render_world(&g.device, &g.queue, &target, world).unwrap();
        let image = read_back(&g.device, &g.queue, &target).unwrap();
        let pass = renderer.packs()[0].fur.as_ref().unwrap().skinning().expect("the Fox is skinned");
        (image, pass.read_back(&g.device, &g.queue).unwrap())
    };
    let running = world_with("animation = { clip = \"Run\", speed = 0.0, start_s = 0.3 }");
    let (run_image, posed) = draw(&running);
    let (bind_image, bind) = draw(&world_with(""));
    g.check().unwrap();
    let mesh = running.pack(0).skin_mesh().unwrap();
    let diag = diagonal(&mesh);
    let cpu = running.animation(0).unwrap().positions();
    let worst = posed
        .positions
        .iter()
        .zip(cpu)
        .map(|(a, b)| Vec3::from(*a).as_dvec3().distance(Vec3::from(*b).as_dvec3()) / diag)
        .fold(0.0, f64::max);
    println!("world pose on the GPU: worst {worst:.2e} × diagonal");
    assert!(worst <= POSITION_TOLERANCE, "GPU pose vs the world's Animator: {worst:e} × diagonal");
    let bind_worst = bind
        .positions
        .iter()
        .zip(&mesh.positions)
        .map(|(a, b)| Vec3::from(*a).as_dvec3().distance(Vec3::from(*b).as_dvec3()) / diag)
        .fold(0.0, f64::max);
    assert!(bind_worst <= POSITION_TOLERANCE, "without an animation the pass keeps the bind pose: {bind_worst:e}");
    let changed = run_image.pixels().zip(bind_image.pixels()).filter(|(a, b)| a != b).count();
    assert!(changed > 100, "the running frame changed only {changed} pixels");
}

/// A scene without a camera frames an animated pack over its whole clip, not its bind pose: every
/// skinned vertex of the Fox walking (sampled at other times than the framing's own poses)
/// projects inside the frame, and the frame differs from the one around the bind pose.
#[test]
fn the_automatic_framing_covers_the_clip_played() {
    let (dir, _) = fox_pack();
    let text = "[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\n[packs.animation]\nclip = \"Walk\"\n";
    let scene = furbake_runtime::Scene::from_toml_str(text, "walk.toml".as_ref(), dir.path()).unwrap();
    let mut world = match furbake_runtime::World::new(scene) {
        Ok(world) => world,
        Err(e) => panic!("{e}"),
    };
    let g = gpu();
    let renderer = furbake_render::SceneRenderer::new(&g.device, &g.queue, &world).unwrap();
    assert!(renderer.packs()[0].clip_bounds.is_some(), "an animated pack has clip bounds");
    let view = renderer.world_view(&world);
    let view_proj = view.view_proj(1.0);
    let bind = renderer.packs()[0].fur.as_ref().unwrap().bounding_sphere();
    assert_ne!(view.bounds_radius, bind.1, "framed on the clip, not the bind pose");
    let mut checked = 0;
    for _ in 0..37 {
        world.step().unwrap();
        let animator = world.animation(0).unwrap();
        for p in animator.positions() {
            let clip = view_proj * world.model_matrix(0).transform_point3(glam::Vec3::from(*p)).extend(1.0);
            let ndc = clip.truncate() / clip.w;
            assert!(
                ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0,
                "a vertex leaves the frame at {:.3} s: {ndc}",
                world.time_s()
            );
            checked += 1;
        }
    }
    assert!(checked > 1000);
}

#[test]
fn renderers_of_one_uploaded_asset_share_its_skin_and_pose_on_their_own() {
    // Two placements of the Fox from one FurGpuAsset: one skinning pipeline and one copy of the
    // influences and morph deltas, but each renderer's own pose and posed vertices — each
    // matches the CPU reference of its own pose, set in either order.
    let g = gpu();
    let asset = FurAsset::from_pack(&fox_pack().1, true).unwrap();
    let shared = FurGpuAsset::new(&g.device, &g.queue, &asset, true).unwrap();
    let make = || {
        FurRenderer::with_gpu_asset(
            g.pipelines(),
            &asset,
            shared.clone(),
            &RenderSettings::default(),
            &RenderTarget::desc(),
        )
        .unwrap()
    };
    let (a, b) = (make(), make());
    let diagonal = diagonal(asset.mesh());
    let poses = [pose_of(fox(), "Run", 0.3, |_| {}), pose_of(fox(), "Survey", 1.1, |_| {})];
    b.set_pose(&g.queue, &poses[1].0, &poses[1].1).unwrap();
    a.set_pose(&g.queue, &poses[0].0, &poses[0].1).unwrap();
    let mut encoder = g.device.create_command_encoder(&Default::default());
    for r in [&a, &b] {
        r.skinning().unwrap().encode(&mut encoder);
    }
    g.queue.submit([encoder.finish()]);
    let mut posed = Vec::new();
    for (r, (palette, weights)) in [&a, &b].into_iter().zip(&poses) {
        let out = r.skinning().unwrap().read_back(&g.device, &g.queue).unwrap();
        let gpu: Posed = out.positions.into_iter().zip(out.normals).collect();
        let cpu = cpu_skin(asset.mesh(), asset.skin_weights(), asset.morph_targets(), palette, weights);
        compare("a placement's own pose", &cpu, &gpu, diagonal);
        posed.push(gpu);
    }
    let apart = posed[0].iter().zip(&posed[1]).filter(|(p, q)| p.0 != q.0).count();
    assert!(apart * 2 > posed[0].len(), "the two placements stand in their own poses ({apart} vertices differ)");
    g.check().unwrap();
}
