//! Skins, morph targets and animation clips (glTF 2.0 specification, "Skins", "Morph Targets",
//! "Animations"): what the import keeps of the generated skinned strip and of the real skinned
//! fixtures, how welding respects influences, and the typed errors and reported repairs of bad
//! skinning data.

use crate::common::fixture;
use furbake_formats::sections::animation_clips::{ChannelTarget, Interpolation};
use furbake_formats::sections::skeleton::Skeleton;
use furbake_import::testmesh::SkinnedStrip;
use furbake_import::{ImportError, ImportSettings, ImportedMesh, import_gltf, import_gltf_slice};

fn import_strip(strip: &SkinnedStrip) -> Result<ImportedMesh, ImportError> {
    import_gltf_slice(&strip.to_gltf(), "strip.gltf", None, &ImportSettings::default())
}

fn import_json(doc: &serde_json::Value) -> Result<ImportedMesh, ImportError> {
    import_gltf_slice(&serde_json::to_vec(doc).unwrap(), "strip.gltf", None, &ImportSettings::default())
}

#[test]
fn the_skinned_strip_keeps_its_skeleton_weights_morph_target_and_clips() {
    let m = import_strip(&SkinnedStrip::default()).unwrap();
    // The skinned-mesh rule: the mesh node's 10 m translation is ignored.
    assert_eq!(m.mesh.bounds(), ([-0.5, 0.0, 0.0], [0.5, 2.0, 0.0]));
    let a = &m.animation;
    let sk = a.skeleton.as_ref().unwrap();
    assert_eq!(sk.names, ["root", "bend"]);
    assert_eq!(sk.parents, [Skeleton::NO_PARENT, 0]);
    assert_eq!(sk.translations[1], [0.0, 1.0, 0.0]);
    assert_eq!(sk.bind_joints, [0, 1]);
    assert_eq!(sk.inverse_binds[1][13], -1.0);
    assert_eq!(sk.skin_root, Some(0));
    let w = a.skin_weights.as_ref().unwrap();
    assert_eq!((w.influences_per_vertex, w.vertex_count()), (4, 6));
    let mut checked = 0;
    for (v, p) in m.mesh.positions.iter().enumerate() {
        let inf: Vec<(u16, f32)> = w.influences(v).filter(|x| x.1 > 0.0).collect();
        let want: Vec<(u16, f32)> = match p[1] {
            0.0 => vec![(0, 1.0)],
            1.0 => vec![(0, 0.5), (1, 0.5)],
            _ => vec![(1, 1.0)],
        };
        assert_eq!(inf, want, "vertex {v} at {p:?}");
        checked += 1;
    }
    assert_eq!(checked, 6);
    assert_eq!(w.stats.renormalised_vertices, 0);
    let morph = a.morph_targets.as_ref().unwrap();
    assert_eq!((morph.target_count(), morph.names[0].as_str(), morph.default_weights[0]), (1, "lift", 0.0));
    for (v, p) in m.mesh.positions.iter().enumerate() {
        let lift = if p[1] == 2.0 { 1.0 } else { 0.0 };
        assert_eq!(morph.positions_of(0)[v], [0.0, 0.0, lift]);
        assert_eq!(morph.normals_of(0)[v], [lift * 0.5, 0.0, 0.0]);
    }
    let clips = a.clips.as_ref().unwrap();
    let names: Vec<&str> = clips.clips.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["Bend", "Step", "Cubic", "Morph"]);
    let cubic = &clips.by_name("Cubic").unwrap().channels[0];
    assert_eq!(
        (cubic.target, cubic.interpolation, cubic.values.len()),
        (ChannelTarget::Translation(0), Interpolation::CubicSpline, 18)
    );
    assert_eq!(clips.by_name("Cubic").unwrap().duration_s, 2.0);
    assert_eq!(clips.by_name("Morph").unwrap().channels[0].target, ChannelTarget::MorphWeights(0));
    assert_eq!(clips.by_name("Step").unwrap().channels[0].interpolation, Interpolation::Step);
}

#[test]
fn coincident_vertices_with_different_influences_do_not_weld() {
    // Cause: welding by position alone gave two skin halves that meet at a seam one vertex with
    // the first half's influences, so the other half tore away from it when animated.
    let mut strip = SkinnedStrip::default();
    strip.positions.extend([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [-0.5, 1.0, 0.0]]);
    strip.joints.extend([[1, 0, 0, 0]; 3]);
    strip.weights.extend([[1.0, 0.0, 0.0, 0.0]; 3]);
    strip.morph_positions.extend([[0.0; 3]; 3]);
    strip.morph_normals.extend([[0.0; 3]; 3]);
    let mut doc = strip.to_json();
    let indexed = import_json(&doc).unwrap();
    assert_eq!(indexed.mesh.positions.len(), 6, "unreferenced extra vertices are dropped");
    // Unindexed: all nine vertices in three triangles.
    doc["meshes"][0]["primitives"][0].as_object_mut().unwrap().remove("indices");
    let m = import_json(&doc).unwrap();
    // Triangles (0,1,2), (3,4,5), (6,7,8): vertices 6,7,8 coincide with 0,1,2 but follow `bend`.
    assert_eq!(m.mesh.positions.len(), 9, "no weld across different influences");
    // With the same influences they weld.
    let mut same = strip.clone();
    same.joints[6..9].copy_from_slice(&[[0, 1, 0, 0]; 3]);
    same.weights[6..9].copy_from_slice(&[[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0]]);
    let mut doc = same.to_json();
    doc["meshes"][0]["primitives"][0].as_object_mut().unwrap().remove("indices");
    assert_eq!(import_json(&doc).unwrap().mesh.positions.len(), 6);
}

#[test]
fn weights_that_do_not_sum_to_one_are_renormalised_and_counted() {
    let mut strip = SkinnedStrip::default();
    strip.weights[2] = [0.25, 0.25, 0.0, 0.0];
    strip.weights[3] = [0.25, 0.25, 0.0, 0.0];
    let m = import_strip(&strip).unwrap();
    let w = m.animation.skin_weights.unwrap();
    assert_eq!(w.stats.renormalised_vertices, 2);
    assert!(w.summary_has_renormalised());
}

/// Weights that sum to 0 (no joint moves the vertex): a reported repair — bound wholly to the
/// skin's first joint, counted with the renormalised vertices, and a warning says so.
#[test]
fn all_zero_weights_bind_the_vertex_to_the_first_joint() {
    let mut strip = SkinnedStrip::default();
    strip.weights[1] = [0.0; 4];
    let m = import_strip(&strip).unwrap();
    let w = m.animation.skin_weights.as_ref().unwrap();
    assert_eq!(w.stats.renormalised_vertices, 1);
    let v = m.mesh.positions.iter().position(|p| *p == strip.positions[1]).unwrap();
    let inf: Vec<(u16, f32)> = w.influences(v).filter(|x| x.1 > 0.0).collect();
    let first = m.animation.skeleton.as_ref().unwrap().bind_joints[inf[0].0 as usize];
    assert_eq!((inf.len(), inf[0].1), (1, 1.0), "{inf:?}");
    assert_eq!(m.animation.skeleton.as_ref().unwrap().names[first as usize], "root");
    assert!(m.warnings.iter().any(|w| w.contains("1 vertices have weights that sum to 0")), "{:?}", m.warnings);
}

trait Renormalised {
    fn summary_has_renormalised(&self) -> bool;
}

impl Renormalised for furbake_formats::sections::skin_weights::SkinWeights {
    fn summary_has_renormalised(&self) -> bool {
        use furbake_formats::Section;
        self.summary()["renormalised_vertices"] == 2
            && (0..6).all(|v| (self.influences(v).map(|x| x.1).sum::<f32>() - 1.0).abs() < 1e-6)
    }
}

#[test]
fn eight_influences_come_from_joints_1_and_weights_1() {
    let strip = SkinnedStrip {
        weights: vec![[0.1, 0.1, 0.0, 0.0]; 6],
        second_set: Some((vec![[1, 0, 1, 0]; 6], vec![[0.2, 0.2, 0.2, 0.2]; 6])),
        ..SkinnedStrip::default()
    };
    let m = import_strip(&strip).unwrap();
    let w = m.animation.skin_weights.unwrap();
    // Joints repeat across slots; the import sums them: joint 0 = 0.1 + 0.2 + 0.2, joint 1 the rest.
    let inf: Vec<(u16, f32)> = w.influences(0).filter(|x| x.1 > 0.0).collect();
    assert_eq!(inf.len(), 2);
    assert!((inf[0].1 - 0.5).abs() < 1e-6 && (inf[1].1 - 0.5).abs() < 1e-6, "{inf:?}");
}

/// Every kind of bad data gives a typed error naming the skin, sampler or primitive and the index.
#[test]
fn bad_skinning_and_animation_data_are_typed_errors() {
    let mut cases: Vec<(&str, Result<ImportedMesh, ImportError>)> = Vec::new();
    let mut s = SkinnedStrip::default();
    s.joints[4] = [0, 7, 0, 0];
    cases.push(("vertex 4: joint index 7 is out of range (skin 0 has 2 joints)", import_strip(&s)));
    let mut s = SkinnedStrip::default();
    s.weights[5] = [f32::NAN, 1.0, 0.0, 0.0];
    cases.push(("vertex 5: weight 0 is not finite", import_strip(&s)));
    let mut s = SkinnedStrip::default();
    s.inverse_binds[1] = [0.0; 16];
    cases.push(("skin 0 \"strip_skin\": the inverse bind matrix of joint 1 is not invertible", import_strip(&s)));
    let mut s = SkinnedStrip::default();
    s.animations[0].channels[0].3 = vec![0.0, 0.0];
    cases.push(("animation 0 \"Bend\", sampler 0: key 1: time 0 s does not increase", import_strip(&s)));
    let mut s = SkinnedStrip::default();
    s.animations[1].channels[0].4.truncate(3);
    cases.push(("animation 1 \"Step\", sampler 0: 3 output values for 2 keys (STEP", import_strip(&s)));
    let mut s = SkinnedStrip::default();
    s.animations[2].channels[0].4.truncate(15);
    cases.push(("15 output values for 2 keys (CUBICSPLINE", import_strip(&s)));
    let mut s = SkinnedStrip::default();
    s.animations[0].channels[0].4[4..8].copy_from_slice(&[0.0; 4]);
    cases.push(("key 1: the rotation is a zero quaternion", import_strip(&s)));
    let mut doc = SkinnedStrip::default().to_json();
    doc["skins"][0]["joints"] = serde_json::json!([0]);
    cases.push(("skin 0 \"strip_skin\": 2 inverse bind matrices for 1 joints", import_json(&doc)));
    let mut checked = 0;
    for (want, r) in cases {
        let err = r.err().unwrap_or_else(|| panic!("{want}: imported"));
        let text = err.to_string();
        assert!(text.starts_with("strip.gltf: "), "{text}");
        assert!(text.contains(want), "want {want:?} in {text}");
        checked += 1;
    }
    assert_eq!(checked, 8);
}

#[test]
fn the_fox_brings_its_skeleton_and_three_clips() {
    let fox = import_gltf(&fixture("Fox.glb"), &ImportSettings::default()).unwrap();
    let a = &fox.animation;
    let sk = a.skeleton.as_ref().unwrap();
    let w = a.skin_weights.as_ref().unwrap();
    assert_eq!(w.vertex_count(), fox.mesh.positions.len());
    assert_eq!(fox.mesh.positions.len(), 290, "welding by influences keeps the published topology");
    assert_eq!(sk.bind_count(), 24, "the fox skin's 24 joints");
    assert!(sk.joint_count() >= 24);
    let names: Vec<&str> = a.clips.as_ref().unwrap().clips.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    for c in &a.clips.as_ref().unwrap().clips {
        assert!(
            c.duration_s > 0.5 && c.channels.len() == 21,
            "{}: {} s, {} channels",
            c.name,
            c.duration_s,
            c.channels.len()
        );
    }
    assert!(a.morph_targets.is_none());
    // The sections decode and agree with each other.
    let sections = furbake_formats::PackSections {
        mesh: Some(&fox.mesh),
        skeleton: Some(sk),
        skin_weights: Some(w),
        clips: a.clips.as_ref(),
        ..Default::default()
    };
    assert!(furbake_formats::check_consistency(&[], &sections).unwrap() > 60);
}

#[test]
fn the_wolf_and_the_truck_are_rigged() {
    let wolf = import_gltf(&fixture("Quaternius_Wolf.glb"), &ImportSettings::default()).unwrap();
    let a = &wolf.animation;
    assert_eq!(a.skeleton.as_ref().unwrap().bind_count(), 51);
    assert_eq!(a.clips.as_ref().unwrap().clips.len(), 12);
    assert_eq!(a.skin_weights.as_ref().unwrap().vertex_count(), wolf.mesh.positions.len());
    // The truck has no skin but animates its wheels: its meshes are bound rigidly to their nodes.
    let truck = import_gltf(&fixture("CesiumMilkTruck.glb"), &ImportSettings::default()).unwrap();
    let a = &truck.animation;
    let w = a.skin_weights.as_ref().unwrap();
    assert_eq!(w.stats.rigid_vertices, truck.mesh.stats.input_vertices);
    assert_eq!(a.skeleton.as_ref().unwrap().bind_count(), 3, "the body and two wheel instances");
    assert_eq!(a.clips.as_ref().unwrap().clips[0].channels.len(), 2);
    // Static files keep no animation sections.
    let b = import_gltf(&fixture("Box.glb"), &ImportSettings::default()).unwrap();
    assert_eq!(b.animation, Default::default());
}

#[test]
fn hostile_skinning_and_animation_values_never_panic() {
    // Every numeric field of the strip's skin, morph target and clips set in turn to a hostile
    // value: the import returns a mesh or a typed error, never a panic.
    let hostile = [f32::NAN, f32::INFINITY, -1.0, 0.0, 1e30, -1e-30];
    let base = SkinnedStrip::default();
    let mut variants: Vec<SkinnedStrip> = Vec::new();
    for &h in &hostile {
        for v in 0..6 {
            for k in 0..4 {
                let mut s = base.clone();
                s.weights[v][k] = h;
                variants.push(s);
            }
            let mut s = base.clone();
            s.morph_positions[v][2] = h;
            variants.push(s);
        }
        for j in 0..2 {
            for e in 0..16 {
                let mut s = base.clone();
                s.inverse_binds[j][e] = h;
                variants.push(s);
            }
        }
        for a in 0..base.animations.len() {
            for t in 0..base.animations[a].channels[0].3.len() {
                let mut s = base.clone();
                s.animations[a].channels[0].3[t] = h;
                variants.push(s);
            }
            for x in 0..base.animations[a].channels[0].4.len() {
                let mut s = base.clone();
                s.animations[a].channels[0].4[x] = h;
                variants.push(s);
            }
        }
    }
    for j in [2u16, 255, u16::MAX] {
        for v in 0..6 {
            let mut s = base.clone();
            s.joints[v][0] = j;
            variants.push(s);
        }
    }
    let (mut ok, mut errors) = (0, 0);
    for (i, s) in variants.iter().enumerate() {
        let r = std::panic::catch_unwind(|| import_strip(s)).unwrap_or_else(|_| panic!("variant {i} panicked"));
        match r {
            Ok(m) => {
                // What imports also encodes and decodes (the decoders' ranges hold).
                use furbake_formats::Section;
                let a = m.animation;
                Skeleton::decode(&a.skeleton.unwrap().encode()).unwrap_or_else(|e| panic!("variant {i}: {e}"));
                furbake_formats::sections::skin_weights::SkinWeights::decode(&a.skin_weights.unwrap().encode())
                    .unwrap_or_else(|e| panic!("variant {i}: {e}"));
                furbake_formats::sections::morph_targets::MorphTargets::decode(&a.morph_targets.unwrap().encode())
                    .unwrap_or_else(|e| panic!("variant {i}: {e}"));
                furbake_formats::sections::animation_clips::AnimationClips::decode(&a.clips.unwrap().encode())
                    .unwrap_or_else(|e| panic!("variant {i}: {e}"));
                ok += 1;
            }
            Err(_) => errors += 1,
        }
    }
    assert_eq!(ok + errors, variants.len());
    assert!(ok > 50 && errors > 50, "{ok} imported, {errors} refused");
}
