// silhouette_common.wgsl — the structs silhouette.wgsl (which selects the silhouette edges) and
// fin.wgsl (which draws fins on them) share; prepended to both (crates/render/src/shaders.rs), as
// WGSL has no includes.

// One interior edge: ends a, b; c the third corner of face 0 (winding a → b → c); d the third
// corner of face 1, whose winding is b → a → d (flags bit 0 clear) or a → b → d (bit 0 set: the
// two faces disagree in orientation); corner_a, corner_b the ends' corner ids (3·triangle +
// corner) in face 0, for scale vectors stored per corner.
struct SilhouetteEdge {
    a: u32,
    b: u32,
    c: u32,
    d: u32,
    corner_a: u32,
    corner_b: u32,
    flags: u32,
    pad0: u32,
};

struct SilhouetteInstance {
    edge: u32,
    fade: f32,
};

