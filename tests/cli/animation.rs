//! Animated inputs end to end (glTF 2.0 specification, "Skins", "Animations"): the Fox bakes with
//! its skeleton, skin weights and clips, `inspect` lists the clips (name, duration, channels,
//! bytes) and the joints, `verify` checks them, and a pack whose clip names a missing joint is
//! refused.

use furbake_formats::sections::animation_clips::{AnimationClips, ChannelTarget};
use furbake_formats::{Pack, PackWriter};

use crate::common::*;
use crate::inspect_json;

#[test]
fn animation_the_fox_pack_lists_its_clips_and_joints() {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("fox.fbk");
    let fox = shared_fixture("Fox.glb");
    assert_ok(&furbake(&["bake", s(&fox), "-o", s(&pack), "--resolution", "32", "-q"]), "bake the fox");
    let verified = furbake(&["verify", s(&pack)]);
    assert_ok(&verified, "verify the fox");
    assert!(stdout(&verified).contains("9 sections"), "{}", stdout(&verified));
    let json = inspect_json(&pack);
    let kinds: Vec<&str> = json["sections"].as_array().unwrap().iter().map(|s| s["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds[6..], ["skeleton", "skin_weights", "animation_clips"]);
    let clips = json["clips"].as_array().unwrap();
    let names: Vec<&str> = clips.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    for c in clips {
        assert_eq!(c["channels"], 21, "{c}");
        assert!(c["duration_s"].as_f64().unwrap() > 0.5 && c["bytes"].as_u64().unwrap() > 1000, "{c}");
    }
    let joints = json["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 25, "24 skin joints and the scene's root node above them");
    assert_eq!(joints[0]["parent"], serde_json::Value::Null);
    assert_eq!(json["statistics"]["clips"], 3);
    let weights = &json["sections"][7];
    assert_eq!((weights["vertices"].as_u64(), weights["renormalised_vertices"].as_u64()), (Some(290), Some(0)));
    let table = stdout(&furbake(&["inspect", s(&pack)]));
    assert!(table.contains("animation_clips") && table.contains("\"Walk\""), "{table}");

    // A clip that drives a joint the skeleton does not have: verify exits 1 naming it.
    let p = Pack::read(&pack).unwrap();
    let mut w = PackWriter::new();
    for (i, e) in p.sections().iter().enumerate() {
        if e.kind == furbake_formats::SectionKind::ANIMATION_CLIPS {
            let mut clips: AnimationClips = p.decode(i).unwrap();
            clips.clips[1].channels[0].target = ChannelTarget::Rotation(99);
            w.push_section(&clips);
        } else {
            w.push(e.kind, e.version, p.payload(i).unwrap().to_vec());
        }
    }
    let bad = dir.path().join("bad.fbk");
    std::fs::write(&bad, w.to_bytes()).unwrap();
    let out = furbake(&["verify", s(&bad)]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("joint 99 is outside the skeleton's 25"), "{}", stderr(&out));
}
