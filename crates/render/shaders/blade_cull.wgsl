// blade_cull.wgsl — which blades the frame draws, and at what detail (grass thesis §5.3 and
// ch. 7; Jahrmann & Wimmer 2017), in four dispatches recorded by `BladeRenderer::prepare`:
//
// 1. `cs_cull_clusters`, one thread per cluster: the cluster's box (its roots' bounds grown by
//    the reach of any pose of its tallest blade, widened as thinning may widen it) against the
//    view frustum and the max distance; then, where the host handed over its depth, against the
//    depth pyramid (occluded: 2).
// 2. `cs_cull_blades`, one thread per blade in blade order, 256 per workgroup (a "block"): a blade
//    of a visible cluster is culled when it is beyond the max distance, dropped by distance
//    thinning, seen edge-on, or when the sphere around its root that holds every pose lies
//    outside a frustum plane; a survivor whose box around that sphere lies behind the depth
//    pyramid is OCCLUDED (as is every blade of an occluded cluster); a surviving blade gets a
//    level of detail from its distance and a fixed random threshold (dithered transitions). Each
//    block counts its blades per LOD.
// 3. `cs_scan_blocks`, one workgroup: exclusive prefix sums of the block counts per LOD, the
//    start of each LOD's instance list, and the `draw_indexed_indirect` arguments per LOD.
// 4. `cs_compact`, one thread per blade: writes each surviving blade's index and its pose-grid
//    coordinates (`blade_grid`, once per drawn blade instead of once per vertex) into its LOD's
//    list at block offset + rank within the block, so every list is in increasing blade order —
//    the same lists every frame for the same inputs, whatever the GPU's scheduling.
//
// With culling off, `cs_pose_all` writes every blade's entry into LOD 0's list instead.
//
// `crates/render/src/culling.rs` is the CPU reference of passes 1–2 (the lists must be equal).

@group(0) @binding(0) var<uniform> cull: CullUniforms;
@group(0) @binding(1) var<storage, read> blades: array<Blade>;
// Per cluster: (min xyz, tallest height scale), (max xyz, unused); min > max for an empty one.
@group(0) @binding(2) var<storage, read> cluster_bounds: array<vec4<f32>>;
// [clusters]: 1 visible, 0 culled, 2 occluded; then [blades]: LOD, CULLED or OCCLUDED.
@group(0) @binding(3) var<storage, read_write> decisions: array<u32>;
// Words 0..20: five draw_indexed_indirect words per LOD; from word 32: per block, 4 words (one
// per LOD) of blade counts, replaced by the block's exclusive offsets in pass 3.
@group(0) @binding(4) var<storage, read_write> work: array<u32>;
// Words 0..4: start of each LOD's list, in entries; then the entries: (blade, μ, α) in three words,
// the blade's pose-grid coordinates evaluated here once so the vertex shader does not.
@group(0) @binding(5) var<storage, read_write> instances: array<u32>;
// What `blade_grid` (grass_pose.wgsl) reads.
@group(0) @binding(6) var<uniform> params: BladeUniforms;
@group(0) @binding(7) var<storage, read> corner_forces: array<vec2<f32>>;
@group(0) @binding(8) var<storage, read> delayed: array<DelayedSource>;
@group(0) @binding(9) var<storage, read> delayed_directions: array<vec2<f32>>;
// The Hi-Z pyramid of the host's depth for this view (a 1 × 1 stand-in when there is none).
@group(0) @binding(10) var pyramid: texture_2d<f32>;

const BLOCK: u32 = 256u;
const BLOCKS_AT: u32 = 32u;
const LISTS_AT: u32 = 4u;

// The largest width factor thinning applies (1 / min density), for the cluster and blade bounds.
fn max_widening() -> f32 {
    return 1.0 / cull.distance.z - 1.0;
}

@compute @workgroup_size(64)
fn cs_cull_clusters(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let c = gid.x + gid.y * groups.x * 64u;
    if c >= cull.counts.y {
        return;
    }
    let lo = cluster_bounds[2u * c];
    let hi = cluster_bounds[2u * c + 1u];
    if lo.x > hi.x {
        decisions[c] = 0u;
        return;
    }
    // Padded for any pose, the thinning's widening and the edge-on thickening (`vs_blade`).
    let r = lo.w * (cull.shape.x + (max_widening() + cull.shape.z * (1.0 + max_widening())) * cull.shape.y);
    let blo = lo.xyz - vec3<f32>(r);
    let bhi = hi.xyz + vec3<f32>(r);
    var visible = 1u;
    for (var k = 0u; k < 6u; k++) {
        let p = cull.planes[k];
        let corner = select(blo, bhi, p.xyz > vec3<f32>(0.0));
        if dot(p.xyz, corner) + p.w < 0.0 {
            visible = 0u;
        }
    }
    let q = clamp(cull.eye.xyz, blo, bhi) - cull.eye.xyz;
    if dot(q, q) > cull.distance.x {
        visible = 0u;
    }
    if visible == 1u && box_occluded(blo, bhi) {
        visible = 2u;
    }
    decisions[c] = visible;
}

// Occlusion (Jahrmann & Wimmer 2017's fourth test) against the Hi-Z pyramid of the depth the
// host drew this frame before the grass (crates/render/src/depth_pyramid.rs): true when the
// pack-frame box [lo, hi] lies wholly behind the farthest depth over its screen rectangle. The
// box's nearest depth is at a corner (depth is monotonic in view distance, which is linear in
// position); the rectangle is read at the level where it spans at most 2 × 2 texels, each the
// farthest depth of the pixels it covers. Conservative: a box reaching the eye's plane or the
// near plane is never occluded.
fn box_occluded(lo: vec3<f32>, hi: vec3<f32>) -> bool {
    let o = cull.occlusion;
    if (o.w & 1u) == 0u {
        return false;
    }
    let reversed = (o.w & 2u) != 0u;
    var smin = vec2<f32>(3.4e38);
    var smax = vec2<f32>(-3.4e38);
    var near = select(3.4e38, -3.4e38, reversed);
    for (var i = 0u; i < 8u; i++) {
        let p = select(lo, hi, vec3<bool>((i & 1u) != 0u, (i & 2u) != 0u, (i & 4u) != 0u));
        let c = cull.clip * vec4<f32>(p, 1.0);
        if !(c.w > 1e-6) {
            return false;
        }
        let ndc = c.xyz / c.w;
        smin = min(smin, ndc.xy);
        smax = max(smax, ndc.xy);
        near = select(min(near, ndc.z), max(near, ndc.z), reversed);
    }
    if !(near >= 0.0 && near <= 1.0) {
        return false;
    }
    // NDC to pixels (y down), clamped to the screen: the part off the screen draws nothing.
    let size = vec2<f32>(f32(o.x), f32(o.y));
    let p0 = clamp(vec2<f32>(smin.x * 0.5 + 0.5, 0.5 - smax.y * 0.5) * size, vec2<f32>(0.0), size - 1.0);
    let p1 = clamp(vec2<f32>(smax.x * 0.5 + 0.5, 0.5 - smin.y * 0.5) * size, vec2<f32>(0.0), size - 1.0);
    var a = vec2<u32>(p0);
    var b = vec2<u32>(p1);
    var level = 0u;
    while level + 1u < o.z && (b.x - a.x > 1u || b.y - a.y > 1u) {
        a = a >> vec2<u32>(1u);
        b = b >> vec2<u32>(1u);
        level += 1u;
    }
    // A level's last texel also covers the odd pixels past it (level sizes halve with floor,
    // down to 1; computed here rather than queried, as the pyramid's own passes size them).
    let last = max(vec2<u32>(o.x, o.y) >> vec2<u32>(level), vec2<u32>(1u)) - vec2<u32>(1u);
    a = min(a, last);
    b = min(b, last);
    var far = select(-3.4e38, 3.4e38, reversed);
    for (var y = a.y; y <= b.y; y++) {
        for (var x = a.x; x <= b.x; x++) {
            let d = textureLoad(pyramid, vec2<u32>(x, y), i32(level)).x;
            far = select(max(far, d), min(far, d), reversed);
        }
    }
    return select(near > far, near < far, reversed);
}

// The block (workgroup) index of a 256-blade pass dispatched as (x, y) workgroups.
fn block_index(wid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return wid.x + wid.y * groups.x;
}

// The LOD of blade `b`, or CULLED (the CPU twin is `CullReference::classify`).
fn classify(b: u32) -> u32 {
    let blade = blades[b];
    let cluster = decisions[blade.cluster];
    if cluster != 1u {
        return select(CULLED, OCCLUDED, cluster == 2u);
    }
    let root = blade.root.xyz;
    let to_eye = cull.eye.xyz - root;
    let d2 = dot(to_eye, to_eye);
    if d2 > cull.distance.x {
        return CULLED;
    }
    let d = sqrt(d2);
    let keep = thinning_keep(cull.distance.y, cull.distance.z, d);
    if blade_random(b, SALT_THINNING) >= keep {
        return CULLED;
    }
    // Edge-on: the view direction close to the width axis (c, 0, −s).
    let across = to_eye.x * blade.yaw.x - to_eye.z * blade.yaw.y;
    if cull.distance.w < 1.0 && across * across > cull.distance.w * d2 {
        return CULLED;
    }
    let r = blade.root.w * (cull.shape.x + (1.0 / keep - 1.0 + cull.shape.z / keep) * cull.shape.y);
    for (var k = 0u; k < 6u; k++) {
        let p = cull.planes[k];
        if dot(p.xyz, root) + p.w < -r {
            return CULLED;
        }
    }
    if box_occluded(root - vec3<f32>(r), root + vec3<f32>(r)) {
        return OCCLUDED;
    }
    let u = blade_random(b, SALT_LOD) - 0.5;
    var lod = 0u;
    if cull.counts.w > 1u && d >= cull.lod.x + u * cull.lod.z {
        lod = 1u;
    }
    if cull.counts.w > 2u && d >= cull.lod.y + u * cull.lod.w {
        lod = 2u;
    }
    return lod;
}

// A blade's contribution to the packed per-LOD counters: 10 bits per LOD (a block holds 256).
fn one_hot(lod: u32) -> u32 {
    return select(1u << (10u * lod), 0u, lod >= 3u);
}

fn unpack_counts(packed: u32) -> vec4<u32> {
    return vec4<u32>(packed & 0x3ffu, (packed >> 10u) & 0x3ffu, (packed >> 20u) & 0x3ffu, 0u);
}

var<workgroup> block_total: atomic<u32>;

@compute @workgroup_size(256)
fn cs_cull_blades(
    @builtin(local_invocation_index) local: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let block = block_index(wid, groups);
    let b = block * BLOCK + local;
    if local == 0u {
        atomicStore(&block_total, 0u);
    }
    workgroupBarrier();
    if b < cull.counts.x {
        let lod = classify(b);
        decisions[cull.counts.y + b] = lod;
        atomicAdd(&block_total, one_hot(lod));
    }
    workgroupBarrier();
    if local == 0u && block < cull.counts.z {
        let n = unpack_counts(atomicLoad(&block_total));
        for (var l = 0u; l < 4u; l++) {
            work[BLOCKS_AT + 4u * block + l] = n[l];
        }
    }
}

var<workgroup> partial: array<vec4<u32>, 256>;

@compute @workgroup_size(256)
fn cs_scan_blocks(@builtin(local_invocation_index) t: u32) {
    let blocks = cull.counts.z;
    let per = (blocks + BLOCK - 1u) / BLOCK;
    let first = min(t * per, blocks);
    let last = min(first + per, blocks);
    var sum = vec4<u32>(0u);
    for (var k = first; k < last; k++) {
        for (var l = 0u; l < 4u; l++) {
            sum[l] += work[BLOCKS_AT + 4u * k + l];
        }
    }
    partial[t] = sum;
    workgroupBarrier();
    // Inclusive Hillis–Steele scan over the 256 threads' sums.
    for (var step = 1u; step < BLOCK; step <<= 1u) {
        var add = vec4<u32>(0u);
        if t >= step {
            add = partial[t - step];
        }
        workgroupBarrier();
        partial[t] += add;
        workgroupBarrier();
    }
    var running = partial[t] - sum;
    for (var k = first; k < last; k++) {
        for (var l = 0u; l < 4u; l++) {
            let n = work[BLOCKS_AT + 4u * k + l];
            work[BLOCKS_AT + 4u * k + l] = running[l];
            running[l] += n;
        }
    }
    if t == 0u {
        let total = partial[BLOCK - 1u];
        var start = 0u;
        for (var l = 0u; l < 4u; l++) {
            instances[l] = start;
            var count = 0u;
            if l < cull.counts.w && l < 3u {
                count = total[l];
            }
            if l < 3u {
                work[5u * l] = cull.index_count[l];
                work[5u * l + 1u] = count;
                work[5u * l + 2u] = cull.first_index[l];
                work[5u * l + 3u] = 0u;
                work[5u * l + 4u] = 0u;
            }
            start += count;
        }
    }
}

var<workgroup> ranks: array<u32, 256>;

@compute @workgroup_size(256)
fn cs_compact(
    @builtin(local_invocation_index) local: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let block = block_index(wid, groups);
    let b = block * BLOCK + local;
    var lod = CULLED;
    if b < cull.counts.x {
        lod = decisions[cull.counts.y + b];
    }
    let mine = one_hot(lod);
    ranks[local] = mine;
    workgroupBarrier();
    for (var step = 1u; step < BLOCK; step <<= 1u) {
        var add = 0u;
        if local >= step {
            add = ranks[local - step];
        }
        workgroupBarrier();
        ranks[local] += add;
        workgroupBarrier();
    }
    if lod < 3u {
        // Blades of this LOD before this one in the block.
        let before = unpack_counts(ranks[local] - mine)[lod];
        let at = instances[lod] + work[BLOCKS_AT + 4u * block + lod] + before;
        write_entry(at, b);
    }
}

// Entry `at` of the lists: blade `b` and its pose-grid coordinates.
fn write_entry(at: u32, b: u32) {
    let grid = blade_grid(b);
    let word = LISTS_AT + 3u * at;
    instances[word] = b;
    instances[word + 1u] = bitcast<u32>(grid.x);
    instances[word + 2u] = bitcast<u32>(grid.y);
}

// With culling off: every blade, in order, in LOD 0's list (the draw is not indirect then).
@compute @workgroup_size(256)
fn cs_pose_all(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let b = gid.x + gid.y * groups.x * BLOCK;
    if b == 0u {
        instances[0] = 0u;
    }
    if b < cull.counts.x {
        write_entry(b, b);
    }
}
