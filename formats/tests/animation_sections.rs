//! The animation sections (glTF 2.0 specification, "Skins", "Morph Targets", "Animations"):
//! skeleton, skin weights, morph targets and clips round-trip, every truncation and a sweep of
//! single-byte corruptions of a pack holding them is rejected without a panic, values outside
//! their documented ranges are refused by the decoders, and `check_consistency` holds the
//! cross-section rules.

use furbake_formats::sections::animation_clips::{
    AnimationClip, AnimationClips, ChannelTarget, ClipChannel, Interpolation,
};
use furbake_formats::sections::morph_targets::{MorphGroup, MorphTargets};
use furbake_formats::sections::skeleton::Skeleton;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::{SkinWeightStats, SkinWeights};
use furbake_formats::{FormatError, HEADER_SIZE, Pack, PackSections, PackWriter, Section, check_consistency};

use crate::rig::{mesh, skeleton};

fn weights() -> SkinWeights {
    let mut w = SkinWeights {
        influences_per_vertex: 4,
        bind_count: 2,
        binds: vec![0; 12],
        weights: vec![0.0; 12],
        stats: SkinWeightStats { renormalised_vertices: 1, skinned_vertices: 3, ..Default::default() },
    };
    w.weights[0] = 1.0;
    w.binds[4] = 1;
    w.weights[4] = 1.0;
    w.binds[8] = 1;
    w.weights[8] = 0.25;
    w.weights[9] = 0.75;
    w
}

fn morphs() -> MorphTargets {
    MorphTargets {
        vertex_count: 3,
        names: vec!["smile".into()],
        groups: vec![MorphGroup { name: "face".into(), first_target: 0, target_count: 1 }],
        position_deltas: vec![[0.0, 0.0, 0.5], [0.0; 3], [0.0; 3]],
        normal_deltas: vec![[0.1, 0.0, 0.0], [0.0; 3], [0.0; 3]],
        default_weights: vec![0.25],
    }
}

fn clips() -> AnimationClips {
    AnimationClips {
        clips: vec![
            AnimationClip {
                name: "Bend".into(),
                duration_s: 1.0,
                channels: vec![
                    ClipChannel {
                        target: ChannelTarget::Rotation(1),
                        interpolation: Interpolation::Linear,
                        components: 4,
                        times_s: vec![0.0, 1.0],
                        values: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.70710677, 0.70710677],
                    },
                    ClipChannel {
                        target: ChannelTarget::Translation(0),
                        interpolation: Interpolation::CubicSpline,
                        components: 3,
                        times_s: vec![0.0, 0.5],
                        values: (0..18).map(|i| i as f32 * 0.1).collect(),
                    },
                ],
            },
            AnimationClip {
                name: "Smile".into(),
                duration_s: 2.0,
                channels: vec![ClipChannel {
                    target: ChannelTarget::MorphWeights(0),
                    interpolation: Interpolation::Step,
                    components: 1,
                    times_s: vec![0.0, 1.0, 2.0],
                    values: vec![0.0, 1.0, 0.5],
                }],
            },
        ],
    }
}

fn pack() -> Vec<u8> {
    let mut w = PackWriter::new();
    w.push_section(&mesh()).push_section(&skeleton()).push_section(&weights()).push_section(&morphs());
    w.push_section(&clips());
    w.to_bytes()
}

fn decode_everything(bytes: &[u8]) -> Result<usize, FormatError> {
    let pack = Pack::from_bytes(bytes)?;
    let (m, s, w, t, c): (SkinMesh, Skeleton, SkinWeights, MorphTargets, AnimationClips) =
        (pack.decode_first()?, pack.decode_first()?, pack.decode_first()?, pack.decode_first()?, pack.decode_first()?);
    let sections = PackSections {
        mesh: Some(&m),
        skeleton: Some(&s),
        skin_weights: Some(&w),
        morph_targets: Some(&t),
        clips: Some(&c),
        ..PackSections::default()
    };
    check_consistency(pack.sections(), &sections)
}

#[test]
fn animation_sections_round_trip_and_are_consistent() {
    let bytes = pack();
    let p = Pack::from_bytes(&bytes).unwrap();
    assert_eq!(*p.skeleton().unwrap().unwrap(), skeleton());
    assert_eq!(*p.skin_weights().unwrap().unwrap(), weights());
    assert_eq!(*p.morph_targets().unwrap().unwrap(), morphs());
    assert_eq!(*p.animation_clips().unwrap().unwrap(), clips());
    let kinds: Vec<String> = p.sections().iter().map(|e| e.kind.to_string()).collect();
    assert_eq!(kinds, ["skin_mesh", "skeleton", "skin_weights", "morph_targets", "animation_clips"]);
    let checks = decode_everything(&bytes).unwrap();
    assert!(checks >= 15, "only {checks} checks");
    assert_eq!(pack(), bytes, "encoding is deterministic");
    let summary = clips().summary();
    assert_eq!(summary["clips"][0]["name"], "Bend");
    assert_eq!(summary["clips"][0]["channels"], 2);
    assert_eq!(summary["clips"][1]["duration_s"], 2.0);
    assert_eq!(skeleton().summary()["joints"], 2);
}

#[test]
fn every_truncation_of_an_animated_pack_is_rejected() {
    let bytes = pack();
    let mut checked = 0;
    for len in 0..bytes.len() {
        let r = std::panic::catch_unwind(|| Pack::from_bytes(&bytes[..len]))
            .unwrap_or_else(|_| panic!("panic on truncation to {len} bytes"));
        assert!(r.is_err(), "truncation to {len} bytes was accepted");
        checked += 1;
    }
    assert_eq!(checked, bytes.len());
}

#[test]
fn single_byte_corruptions_of_an_animated_pack_are_rejected() {
    let bytes = pack();
    let mut rejected = 0;
    for at in 0..bytes.len() {
        for flip in [0x01u8, 0x80, 0xff] {
            let mut b = bytes.clone();
            b[at] ^= flip;
            let r = std::panic::catch_unwind(|| decode_everything(&b))
                .unwrap_or_else(|_| panic!("panic with byte {at} ^ {flip:#x}"));
            if r.is_err() {
                rejected += 1;
            }
        }
    }
    let p = Pack::from_bytes(&bytes).unwrap();
    let covered = HEADER_SIZE + p.sections().len() * 32 + p.sections().iter().map(|e| e.length as usize).sum::<usize>();
    assert!(rejected >= covered * 3 - 48 * 3, "only {rejected} of {} corruptions rejected", covered * 3);
}

#[test]
fn values_outside_their_documented_ranges_are_rejected() {
    // Decoders refuse what no bake writes, so a pack that reads also animates in bounded time.
    let mut cases: Vec<(&str, Result<(), FormatError>)> = Vec::new();
    let mut s = skeleton();
    s.parents[0] = 1;
    cases.push(("topological order", Skeleton::decode(&s.encode()).map(|_| ())));
    let mut s = skeleton();
    s.rotations[1] = [0.0, 0.0, 0.0, 0.5];
    cases.push(("unit quaternion", Skeleton::decode(&s.encode()).map(|_| ())));
    let mut s = skeleton();
    s.inverse_binds[0] = [0.0; 16];
    cases.push(("not invertible", Skeleton::decode(&s.encode()).map(|_| ())));
    let mut s = skeleton();
    s.bind_joints[1] = 5;
    cases.push(("bind joints", Skeleton::decode(&s.encode()).map(|_| ())));
    let mut s = skeleton();
    s.nodes.pop();
    cases.push(("joint nodes", Skeleton::decode(&s.encode()).map(|_| ())));
    let mut s = skeleton();
    s.nodes = vec![4, 4];
    cases.push(("two joints", Skeleton::decode(&s.encode()).map(|_| ())));
    let mut w = weights();
    w.weights[9] = 0.5;
    cases.push(("sum to 1", SkinWeights::decode(&w.encode()).map(|_| ())));
    let mut w = weights();
    w.binds[1] = 7;
    cases.push(("binds", SkinWeights::decode(&w.encode()).map(|_| ())));
    let mut w = weights();
    w.weights[0] = f32::NAN;
    cases.push(("not finite", SkinWeights::decode(&w.encode()).map(|_| ())));
    let mut m = morphs();
    m.default_weights[0] = 1e9;
    cases.push(("default weights", MorphTargets::decode(&m.encode()).map(|_| ())));
    let mut m = morphs();
    m.groups[0].target_count = 2;
    cases.push(("groups", MorphTargets::decode(&m.encode()).map(|_| ())));
    let mut c = clips();
    c.clips[1].channels[0].times_s = vec![0.0, 1.0, 1.0];
    cases.push(("not increasing", AnimationClips::decode(&c.encode()).map(|_| ())));
    let mut c = clips();
    c.clips[0].channels[0].values[7] = 0.1;
    cases.push(("unit quaternion", AnimationClips::decode(&c.encode()).map(|_| ())));
    let mut c = clips();
    c.clips[0].duration_s = 0.5;
    cases.push(("key times", AnimationClips::decode(&c.encode()).map(|_| ())));
    let mut c = clips();
    c.clips[0].channels[1].values.pop();
    cases.push(("run past", AnimationClips::decode(&c.encode()).map(|_| ())));
    let mut rejected = 0;
    for (what, r) in cases {
        let err = r.expect_err(what);
        assert!(err.is_bad_file() && err.to_string().contains(what), "{what}: {err}");
        rejected += 1;
    }
    assert_eq!(rejected, 15);
}

/// The skeleton's layout 2 records each joint's glTF node; layout 1 (a pack baked before) reads
/// with none.
#[test]
fn skeleton_layout_1_reads_without_joint_nodes() {
    let s = skeleton();
    assert_eq!(Skeleton::decode(&s.encode()).unwrap(), s, "layout 2 round trip");
    // Layout 1: the same record without array 6.
    #[derive(serde::Serialize)]
    struct MetaV1 {
        joint_count: u32,
        bind_count: u32,
        skin_root: Option<u32>,
        names: Vec<String>,
    }
    let meta = MetaV1 { joint_count: 2, bind_count: 2, skin_root: s.skin_root, names: s.names.clone() };
    let v1 = furbake_formats::record::RecordWriter::new(&meta)
        .array::<u32>(&s.parents)
        .array::<f32>(s.translations.as_flattened())
        .array::<f32>(s.rotations.as_flattened())
        .array::<f32>(s.scales.as_flattened())
        .array::<u32>(&s.bind_joints)
        .array::<f32>(s.inverse_binds.as_flattened())
        .finish();
    let read = Skeleton::decode(&v1).unwrap();
    assert!(read.nodes.is_empty());
    assert_eq!(Skeleton { nodes: s.nodes.clone(), ..read }, s);
}

#[test]
fn cross_section_rules_are_checked() {
    let (m, s, w, t, c) = (mesh(), skeleton(), weights(), morphs(), clips());
    let base = PackSections {
        mesh: Some(&m),
        skeleton: Some(&s),
        skin_weights: Some(&w),
        morph_targets: Some(&t),
        clips: Some(&c),
        ..PackSections::default()
    };
    assert!(check_consistency(&[], &base).is_ok());
    let mut more = mesh();
    more.positions.push([0.0; 3]);
    more.normals.push([0.0, 0.0, 1.0]);
    more.colors.push([1.0; 4]);
    let mut one_bind = skeleton();
    one_bind.bind_joints.pop();
    one_bind.inverse_binds.pop();
    let mut bad_joint = clips();
    bad_joint.clips[0].channels[0].target = ChannelTarget::Rotation(9);
    let mut bad_group = clips();
    bad_group.clips[1].channels[0].target = ChannelTarget::MorphWeights(3);
    let mut bad_width = clips();
    bad_width.clips[1].channels[0].components = 2;
    bad_width.clips[1].channels[0].values = vec![0.0; 6];
    let cases: Vec<(&str, PackSections<'_>)> = vec![
        (
            "skin_weights: 3 vertices, the skin mesh has 4",
            PackSections { mesh: Some(&more), morph_targets: None, ..base },
        ),
        ("morph_targets: 3 vertices", PackSections { mesh: Some(&more), skin_weights: None, ..base }),
        ("written for 2 binds, the skeleton has 1", PackSections { skeleton: Some(&one_bind), ..base }),
        ("joint 9 is outside", PackSections { clips: Some(&bad_joint), ..base }),
        ("morph group 3 is outside", PackSections { clips: Some(&bad_group), ..base }),
        ("2 weights per key, the group has 1", PackSections { clips: Some(&bad_width), ..base }),
    ];
    let mut checked = 0;
    for (want, sections) in cases {
        let err = check_consistency(&[], &sections).unwrap_err().to_string();
        assert!(err.contains(want), "{want}: {err}");
        checked += 1;
    }
    assert_eq!(checked, 6);
    // From the table: clips driving joints in a pack without a skeleton.
    let mut wr = PackWriter::new();
    wr.push_section(&mesh()).push_section(&clips());
    let p = Pack::from_bytes(&wr.to_bytes()).unwrap();
    let c2 = clips();
    let err = check_consistency(p.sections(), &PackSections { clips: Some(&c2), ..PackSections::default() })
        .unwrap_err()
        .to_string();
    assert!(err.contains("no skeleton") || err.contains("no morph targets"), "{err}");
}
