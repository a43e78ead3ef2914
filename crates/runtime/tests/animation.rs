//! The CPU reference of character animation (glTF 2.0 specification, "Animations" →
//! "Interpolation", "Skins", "Morph Targets") against hand-computed values: each interpolation
//! mode, a two-joint bend, a morph target at weight 0.5, normals under a non-uniform scale, a
//! cross-fade, and the real Fox and Wolf posed mid-walk (finite, inside the bound that rigid
//! joints allow, legs moved).

use std::path::PathBuf;

use furbake_formats::sections::animation_clips::AnimationClips;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_import::testmesh::SkinnedStrip;
use furbake_import::{ImportSettings, ImportedMesh, import_gltf, import_gltf_slice};
use furbake_runtime::animation::{
    AnimationError, AnimationPlayer, Pose, joint_world_matrices, morph_and_skin, sample_clip, skinning_matrices,
};
use glam::{Mat4, Quat, Vec3};

fn strip() -> ImportedMesh {
    import_gltf_slice(&SkinnedStrip::default().to_gltf(), "strip.gltf", None, &ImportSettings::default()).unwrap()
}

fn clips(m: &ImportedMesh) -> &AnimationClips {
    m.animation.clips.as_ref().unwrap()
}

/// Poses `m` with `pose` and returns the skinned positions and normals.
fn skin(m: &ImportedMesh, pose: &Pose) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let a = &m.animation;
    let sk = a.skeleton.as_ref().unwrap();
    let mut world = vec![Mat4::IDENTITY; sk.joint_count()];
    let mut palette = vec![Mat4::IDENTITY; sk.bind_count()];
    joint_world_matrices(sk, pose, &mut world).unwrap();
    skinning_matrices(sk, &world, &mut palette).unwrap();
    let v = m.mesh.positions.len();
    let (mut p, mut n) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v]);
    let morphs = a.morph_targets.as_ref().map(|t| (t, pose.morph_weights.as_slice()));
    morph_and_skin(&m.mesh, a.skin_weights.as_ref(), morphs, &palette, &mut p, &mut n).unwrap();
    (p, n)
}

fn pose_at(m: &ImportedMesh, clip: &str, t: f32) -> Pose {
    let a = &m.animation;
    let mut pose = Pose::rest(a.skeleton.as_ref(), a.morph_targets.as_ref());
    let groups = a.morph_targets.as_ref().map_or(&[][..], |t| &t.groups[..]);
    sample_clip(clips(m).by_name(clip).unwrap(), t, groups, &mut pose);
    pose
}

fn close(a: impl Into<Vec3>, b: impl Into<Vec3>, tol: f32) -> bool {
    (a.into() - b.into()).length() <= tol
}

/// The index of the strip vertex at `p`.
fn at(m: &ImportedMesh, p: [f32; 3]) -> usize {
    m.mesh.positions.iter().position(|q| *q == p).unwrap()
}

#[test]
fn each_interpolation_mode_matches_hand_computed_values() {
    let m = strip();
    // LINEAR rotation: halfway between identity and 90° about z is 45° about z (slerp).
    let half = pose_at(&m, "Bend", 0.5).rotations[1];
    let want = Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
    assert!(half.angle_between(want) < 1e-5, "{half}");
    // Clamped outside the keys: before the first the first value, after the last the last.
    assert!(pose_at(&m, "Bend", -1.0).rotations[1].angle_between(Quat::IDENTITY) < 1e-6);
    assert!(pose_at(&m, "Bend", 7.0).rotations[1].angle_between(Quat::from_rotation_z(1.5707964)) < 1e-5);
    // STEP: the value of the last key at or before the time.
    assert_eq!(pose_at(&m, "Step", 0.99).translations[0], Vec3::ZERO);
    assert_eq!(pose_at(&m, "Step", 1.0).translations[0], Vec3::X);
    assert_eq!(pose_at(&m, "Step", 5.0).translations[0], Vec3::X);
    // CUBICSPLINE over [0, 2] s (td = 2), v0 = 0, out-tangent b0 = 3, v1 = 1, in-tangent a1 = 3:
    // p(s) = (2s³−3s²+1)v0 + td(s³−2s²+s)b0 + (−2s³+3s²)v1 + td(s³−s²)a1.
    // s = 0.25: 0.28125·3 + 0.15625·1 − 0.09375·3 = 0.71875; s = 0.5: 0.75 + 0.5 − 0.75 = 0.5.
    let x = |t: f32| pose_at(&m, "Cubic", t).translations[0].x;
    assert!((x(0.5) - 0.71875).abs() < 1e-6, "{}", x(0.5));
    assert!((x(1.0) - 0.5).abs() < 1e-6, "{}", x(1.0));
    assert!((x(1.5) - 0.28125).abs() < 1e-6, "{}", x(1.5));
    assert_eq!((x(0.0), x(2.0)), (0.0, 1.0));
    // LINEAR morph weights.
    assert!((pose_at(&m, "Morph", 0.25).morph_weights[0] - 0.25).abs() < 1e-7);
}

#[test]
fn a_two_joint_bend_skins_by_hand() {
    // `bend` turns 90° about z around (0, 1, 0): the top row (all `bend`) swings to x = −1,
    // the middle row (½ root, ½ bend) lands halfway between staying and turning, the bottom stays.
    let m = strip();
    let (p, n) = skin(&m, &pose_at(&m, "Bend", 1.0));
    let cases = [
        ([0.5, 2.0, 0.0], [-1.0, 1.5, 0.0]),
        ([-0.5, 2.0, 0.0], [-1.0, 0.5, 0.0]),
        ([0.5, 1.0, 0.0], [0.25, 1.25, 0.0]),
        ([-0.5, 1.0, 0.0], [-0.25, 0.75, 0.0]),
        ([0.5, 0.0, 0.0], [0.5, 0.0, 0.0]),
    ];
    let mut checked = 0;
    for (rest, want) in cases {
        let v = at(&m, rest);
        assert!(close(p[v], want, 1e-5), "{rest:?} → {:?}, want {want:?}", p[v]);
        assert!(close(n[v], [0.0, 0.0, 1.0], 1e-5), "a turn about z keeps +z normals: {:?}", n[v]);
        checked += 1;
    }
    assert_eq!(checked, 5);
    // At rest the skin reproduces the stored mesh (world × inverse bind = identity).
    let (rest, _) = skin(&m, &Pose::rest(m.animation.skeleton.as_ref(), None).with_weights(1));
    assert_eq!(rest, m.mesh.positions);
}

trait WithWeights {
    fn with_weights(self, n: usize) -> Self;
}

impl WithWeights for Pose {
    fn with_weights(mut self, n: usize) -> Self {
        self.morph_weights = vec![0.0; n];
        self
    }
}

#[test]
fn a_morph_target_at_weight_one_half() {
    // The `lift` target moves the top row +1 in z and its normals +0.5 in x: at weight 0.5 the
    // top row is at z = 0.5 and its normal is normalize(0.25, 0, 1).
    let m = strip();
    let pose = pose_at(&m, "Morph", 0.5);
    assert!((pose.morph_weights[0] - 0.5).abs() < 1e-7);
    let (p, n) = skin(&m, &pose);
    let want_n = Vec3::new(0.25, 0.0, 1.0).normalize();
    let mut checked = 0;
    for (v, rest) in m.mesh.positions.iter().enumerate() {
        if rest[1] == 2.0 {
            assert!(close(p[v], [rest[0], 2.0, 0.5], 1e-6), "{:?}", p[v]);
            assert!(close(n[v], want_n, 1e-6), "{:?}", n[v]);
        } else {
            assert_eq!(p[v], *rest);
            assert!(close(n[v], [0.0, 0.0, 1.0], 1e-6));
        }
        checked += 1;
    }
    assert_eq!(checked, 6);
}

#[test]
fn normals_follow_the_inverse_transpose_under_a_non_uniform_scale() {
    // Cause of the peers' most reported bug: normals transformed by the skinning matrix itself
    // tilt under non-uniform scale. A surface with tangent (1, −1, 0) and normal (1, 1, 0)/√2,
    // scaled ×2 in x: the tangent becomes (2, −1, 0); the normal must stay perpendicular to it,
    // normalize(0.5, 1, 0) — not normalize(2, 1, 0).
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let mesh = SkinMesh { positions: vec![[1.0, 0.0, 0.0]], normals: vec![[s, s, 0.0]], ..SkinMesh::default() };
    let weights = SkinWeights {
        influences_per_vertex: 4,
        bind_count: 1,
        binds: vec![0; 4],
        weights: vec![1.0, 0.0, 0.0, 0.0],
        ..SkinWeights::default()
    };
    let palette = [Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0))];
    let (mut p, mut n) = ([[0.0; 3]], [[0.0; 3]]);
    morph_and_skin(&mesh, Some(&weights), None, &palette, &mut p, &mut n).unwrap();
    assert_eq!(p[0], [2.0, 0.0, 0.0]);
    let n = Vec3::from(n[0]);
    assert!(close(n, Vec3::new(0.5, 1.0, 0.0).normalize(), 1e-6), "{n}");
    assert!(n.dot(Vec3::new(2.0, -1.0, 0.0)).abs() < 1e-6, "perpendicular to the scaled tangent");
    // A mirroring scale keeps the normal outward (cofactor × sign of the determinant).
    let mirror = [Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))];
    let (mut p, mut n) = ([[0.0; 3]], [[0.0; 3]]);
    morph_and_skin(&mesh, Some(&weights), None, &mirror, &mut p, &mut n).unwrap();
    assert!(close(n[0], [-s, s, 0.0], 1e-6), "{:?}", n[0]);
    // A joint scaled to zero collapses the vertex but leaves a finite (rest) normal.
    let zero = [Mat4::from_scale(Vec3::ZERO)];
    morph_and_skin(&mesh, Some(&weights), None, &zero, &mut p, &mut n).unwrap();
    assert_eq!((p[0], n[0]), ([0.0; 3], [s, s, 0.0]));
}

#[test]
fn the_player_loops_clamps_and_cross_fades() {
    let m = strip();
    let (a, c) = (&m.animation, clips(&m));
    let groups = &a.morph_targets.as_ref().unwrap().groups;
    let mut out = Pose::rest(a.skeleton.as_ref(), a.morph_targets.as_ref());
    let mut player =
        AnimationPlayer::new(c, "Cubic", 1.0, true, a.skeleton.as_ref(), a.morph_targets.as_ref()).unwrap();
    player.advance(c, 1.0);
    player.pose(c, groups, &mut out).unwrap();
    assert!((out.translations[0].x - 0.5).abs() < 1e-6);
    // Cross-fade to Step over 1 s; half-way the pose is the mean of Cubic at 1.5 s (0.28125) and
    // Step at 0.5 s (0).
    player.play(c, "Step", 1.0).unwrap();
    player.advance(c, 0.5);
    assert!((player.fade_weight() - 0.5).abs() < 1e-6);
    player.pose(c, groups, &mut out).unwrap();
    assert!((out.translations[0].x - 0.140625).abs() < 1e-6, "{}", out.translations[0].x);
    // The fade ends; Step (1 s long) loops: 0.5 + 1.0 → 0.5 again.
    player.advance(c, 1.0);
    assert_eq!(player.fade_weight(), 1.0);
    assert!((player.current().time_s - 0.5).abs() < 1e-6);
    player.pose(c, groups, &mut out).unwrap();
    assert_eq!(out.translations[0], Vec3::ZERO);
    // Without looping the clip holds its end; at double speed 0.6 s reach the end of a 1 s clip.
    let mut once = AnimationPlayer::new(c, "Step", 2.0, false, a.skeleton.as_ref(), a.morph_targets.as_ref()).unwrap();
    once.advance(c, 0.6);
    assert_eq!(once.current().time_s, 1.0);
    once.pose(c, groups, &mut out).unwrap();
    assert_eq!(out.translations[0], Vec3::X);
    // A clip the pack does not have names the ones it has.
    let err = AnimationPlayer::new(c, "Dance", 1.0, true, None, None).unwrap_err();
    assert_eq!(err, AnimationError::UnknownClip { name: "Dance".into(), known: "Bend, Step, Cubic, Morph".into() });
}

/// A real model bundled in the repository's `fixtures/real/` (licences beside them).
fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real").join(name)
}

/// Poses a real character at `t` of `clip` and checks the skin: finite, every vertex inside the
/// box of the posed joints grown by the largest bind-pose distance from a vertex to a joint that
/// influences it (the reach linear blend skinning allows under rigid joints), and some vertex
/// moved by more than 1 % of the diagonal (the legs). Returns the vertices checked.
fn check_posed(name: &str, clip: &str, t: f32) -> usize {
    let m = import_gltf(&fixture(name), &ImportSettings::default()).unwrap();
    let a = &m.animation;
    let (sk, w) = (a.skeleton.as_ref().unwrap(), a.skin_weights.as_ref().unwrap());
    let mut player = AnimationPlayer::new(clips(&m), clip, 1.0, true, Some(sk), a.morph_targets.as_ref()).unwrap();
    player.advance(clips(&m), t);
    let mut pose = Pose::rest(Some(sk), a.morph_targets.as_ref());
    player.pose(clips(&m), &[], &mut pose).unwrap();
    let (p, n) = skin(&m, &pose);
    let mut world = vec![Mat4::IDENTITY; sk.joint_count()];
    joint_world_matrices(sk, &pose, &mut world).unwrap();
    // Bind-pose joint positions: the inverse of each inverse bind, applied to the origin.
    let bind_pos: Vec<Vec3> =
        sk.inverse_binds.iter().map(|m| Mat4::from_cols_array(m).inverse().transform_point3(Vec3::ZERO)).collect();
    let mut reach = 0.0f32;
    for (v, q) in m.mesh.positions.iter().enumerate() {
        for (b, wi) in w.influences(v) {
            if wi > 0.0 {
                reach = reach.max(Vec3::from(*q).distance(bind_pos[b as usize]));
            }
        }
    }
    let posed_joints: Vec<Vec3> =
        sk.bind_joints.iter().map(|&j| world[j as usize].transform_point3(Vec3::ZERO)).collect();
    let lo = posed_joints.iter().fold(Vec3::INFINITY, |a, &b| a.min(b)) - Vec3::splat(reach * 1.001);
    let hi = posed_joints.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b)) + Vec3::splat(reach * 1.001);
    let (rlo, rhi) = m.mesh.bounds();
    let diag = Vec3::from(rhi).distance(Vec3::from(rlo));
    let mut moved = 0.0f32;
    let mut checked = 0;
    for (v, (q, nn)) in p.iter().zip(&n).enumerate() {
        let q = Vec3::from(*q);
        assert!(q.is_finite() && Vec3::from(*nn).is_finite(), "{name}: vertex {v} is not finite");
        assert!((Vec3::from(*nn).length() - 1.0).abs() < 1e-4, "{name}: normal {v} is not unit");
        assert!(q.cmpge(lo).all() && q.cmple(hi).all(), "{name}: vertex {v} at {q} is outside {lo}..{hi}");
        moved = moved.max(q.distance(Vec3::from(m.mesh.positions[v])));
        checked += 1;
    }
    assert!(moved > 0.01 * diag, "{name}: {clip} at {t} s moved no vertex by 1 % of {diag}");
    checked
}

#[test]
fn the_fox_posed_mid_walk_stays_finite_and_within_its_joints_reach() {
    assert_eq!(check_posed("Fox.glb", "Walk", 0.5), 290);
}

#[test]
fn the_wolf_posed_mid_walk_stays_finite_and_within_its_joints_reach() {
    assert!(check_posed("Quaternius_Wolf.glb", "Walk", 0.5) > 900);
}
