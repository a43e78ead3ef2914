// Fur physics in compute: the explicit and stick mass–spring solvers of the fur thesis (§3.3.2,
// eq. 3.20–3.25; §3.4.1 sticks), XPBD over the coloured links (crates/sim/src/solvers/xpbd.rs),
// the wrong-side guard (§3.4.3) and the scale vectors (eq. 3.35)
// written into the buffer the shell shader reads. The CPU twin is furbake-sim's lane-group kernel
// (crates/sim/src/solvers/fused.rs) over the flat model of crates/sim/src/compute.rs; the data
// layouts are crates/render/src/physics.rs. One invocation per free mass gathers its own links in
// adjacency order, so the result does not depend on scheduling.
//
// A herd: the packs of one asset step together, their per-pack arrays laid one after another in
// the same buffers, one dispatch per pass for up to HERD_CHUNK packs (the dispatch's y). Each pack
// has its own substep uniforms (`steps[si]`, si = the invocation's y) holding where its part of
// each array starts (`base`, `base2`); the indices stored in the arrays (link ends, parents, tips'
// masses) already include those starts, while the arrays the asset shares (bind pose, links
// between hairs, skin influences, shell-vertex tips, XPBD colours) hold indices within one pack.

const NO_LINK: u32 = 0xffffffffu;
const LOCALS: u32 = 16u;
const TAU: f32 = 6.283185307179586;

struct PhysicsStep {
    // xyz: gravity − frame acceleration (m/s²); w: substep length h (s)
    accel: vec4<f32>,
    // xyz: frame angular velocity (rad/s); w: time at the substep's start (s)
    omega: vec4<f32>,
    // xyz: frame angular acceleration (rad/s²); w: restoring weight (N, eq. 3.37)
    alpha: vec4<f32>,
    // xyz: wind direction (unit); w: mean wind force (N)
    wind_dir: vec4<f32>,
    // gust amplitude, gust frequency (Hz), 1/gust wavelength (1/m), wind on (1) or off (0)
    wind: vec4<f32>,
    // cos of the guard angle, guard impulse (m/s), guard on (1) or off (0), unused
    guard: vec4<f32>,
    // free masses, tips, shell vertices, local forces
    counts: vec4<u32>,
    // update (0 explicit, 1 stick, 2 XPBD), project sticks (1), rotating frame (1), unused
    flags: vec4<u32>,
    // xyz: the teleport applied before this step (m, mesh frame; cs_teleport); w: 1 where there is
    // one (a herd's other packs skip the pass)
    teleport: vec4<f32>,
    // the skin's pose before this step (cs_pose_*): 1/step (1/s), cut speed (m/s), posed (1: the
    // pose passes run for this pack), blended (1: cs_pose_blend runs for it)
    pose: vec4<f32>,
    // the pose's first transform, its speed slot, every mass, links between hairs
    pose_at: vec4<u32>,
    // a pose blended here (cs_pose_blend): its first skinning matrix, its first morph weight,
    // influence slots per vertex | morph targets << 8, welded skin vertices
    pose_skin: vec4<u32>,
    // per local force: centre xyz and radius w (m), then strength x (N)
    locals: array<vec4<f32>, 32>,
    // where this pack's part starts: its first mass, link entry, tip and shell vertex
    base: vec4<u32>,
    // its first XPBD link, its counters' slot, unused, unused
    base2: vec4<u32>,
    pad0: vec4<u32>,
    pad1: vec4<u32>,
}

// The packs one dispatch steps (the uniform array's length: 64 × 768 bytes fits WebGPU's smallest
// uniform binding of 64 KiB).
const HERD_CHUNK: u32 = 64u;

struct PhysicsMass {
    // the restoring link's rest direction (xyz) and rest length (w, m)
    restoring_n: vec4<f32>,
    // this mass's rest position (xyz; the wind's phase, the stick fallback)
    rest_pos: vec4<f32>,
    // the anchored stick parent's position (xyz)
    stick_anchor: vec4<f32>,
    mass: f32,
    inv_mass: f32,
    links_start: u32,
    links_end: u32,
    restoring_parent: u32,
    stick_parent: u32,
    stick_len: f32,
    stick_c: f32,
}

struct PhysicsLink {
    other: u32,
    rest: f32,
    k: f32,
    c: f32,
}

struct PhysicsTip {
    // the rest direction (xyz)
    n: vec4<f32>,
    // the anchored root's position (xyz)
    root_pos: vec4<f32>,
    root: u32,
    tip: u32,
    pad0: u32,
    pad1: u32,
}

// Each pack's uniforms of this substep (the dynamic offset picks the substep and the chunk).
@group(0) @binding(0) var<uniform> steps: array<PhysicsStep, HERD_CHUNK>;
// The invoking pack's slot in `steps` (every entry point sets it first).
var<private> si: u32;
@group(0) @binding(1) var<storage, read> x_in: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> v_in: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> x_out: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> v_out: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> masses: array<PhysicsMass>;
@group(0) @binding(7) var<storage, read> links: array<PhysicsLink>;
// per pack: non-finite masses, guard triggers, frozen tips, unused (read back only when asked for)
@group(0) @binding(8) var<storage, read_write> stats: array<atomic<u32>>;

// Adds to this pack's counter `c`.
fn count(c: u32) {
    atomicAdd(&stats[4u * steps[si].base2.y + c], 1u);
}

fn finite3(v: vec3<f32>) -> bool {
    // NaN fails every comparison; ±inf exceeds the largest finite float.
    return all(abs(v) <= vec3<f32>(3.4028235e38));
}

// The external forces on free mass k (crates/sim/src/forces.rs ForceEval::external).
fn external_force(pm: PhysicsMass, x: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let m = pm.mass;
    var f = steps[si].accel.xyz * m;
    if steps[si].flags.z != 0u {
        let w = steps[si].omega.xyz;
        let inertial = cross(steps[si].alpha.xyz, x) + cross(w, cross(w, x)) + 2.0 * cross(w, v);
        f = f - inertial * m;
    }
    if steps[si].wind.w != 0.0 {
        let d = steps[si].wind_dir.xyz;
        let phase = TAU * (steps[si].wind.y * steps[si].omega.w - dot(d, pm.rest_pos.xyz) * steps[si].wind.z);
        f = f + d * (steps[si].wind_dir.w * (1.0 + steps[si].wind.x * sin(phase)));
    }
    for (var i = 0u; i < min(steps[si].counts.w, LOCALS); i++) {
        let c = steps[si].locals[2u * i];
        let delta = x - c.xyz;
        let dist = length(delta);
        if dist < c.w && dist > 1e-12 {
            let fall = 1.0 - dist / c.w;
            f = f + delta * (steps[si].locals[2u * i + 1u].x * fall * fall / dist);
        }
    }
    return f;
}

// The restoring force of eq. 3.37 on a free mass at `xi`, towards its rest direction.
fn restoring_force(m: PhysicsMass, xi: vec3<f32>) -> vec3<f32> {
    let w = steps[si].alpha.w;
    if w == 0.0 || m.restoring_parent == NO_LINK {
        return vec3<f32>(0.0);
    }
    let s = xi - x_in[m.restoring_parent].xyz;
    let rcp = 1.0 / sqrt(dot(s, s));
    if !(rcp > 0.0 && rcp <= 3.4028235e38) {
        return vec3<f32>(0.0);
    }
    let sn = s * rcp;
    return (m.restoring_n.xyz - sn) * ((1.0 - dot(m.restoring_n.xyz, sn)) * w);
}

// Puts a free mass back at its stick's length from its anchored parent and removes its velocity
// along the stick (crates/sim/src/solvers/projection.rs).
fn project_on_stick(m: PhysicsMass, x: ptr<function, vec3<f32>>, v: ptr<function, vec3<f32>>) {
    let xp = m.stick_anchor.xyz;
    var e = *x - xp;
    if dot(e, e) == 0.0 {
        e = m.rest_pos.xyz - xp;
    }
    let dir = normalize(e);
    *x = xp + dir * m.stick_len;
    *v = *v - dir * dot(*v, dir);
}

// One substep of one free mass: forces at the substep's start, the velocity update, the move
// and the projection onto an anchored stick.
@compute @workgroup_size(64)
fn cs_step(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    if gid.x >= steps[si].counts.x {
        return;
    }
    let k = steps[si].base.x + gid.x;
    let m = masses[k];
    let xi = x_in[k].xyz;
    let vi = v_in[k].xyz;
    let h = steps[si].accel.w;
    // Links (Hooke eq. 3.23 + viscosity eq. 3.24) from this mass's side, in adjacency order.
    var fl = vec3<f32>(0.0);
    for (var e = m.links_start; e < m.links_end; e++) {
        let l = links[e];
        let d = x_in[l.other].xyz - xi;
        let dv = v_in[l.other].xyz - vi;
        let t = l.k * (1.0 - l.rest / max(length(d), 1e-20));
        fl = fl + fma(d, vec3<f32>(t), dv * l.c);
    }
    let f = (external_force(m, xi, vi) + restoring_force(m, xi)) + fl;
    let s = h * m.inv_mass;
    var vn = vi + f * s;
    if steps[si].flags.x == 1u && m.stick_parent != NO_LINK {
        // The stick solver damps the rigid link implicitly towards the parent's velocity.
        let ac = s * m.stick_c;
        vn = (vn + v_in[m.stick_parent].xyz * ac) / (1.0 + ac);
    }
    write_state(k, m, xi + vn * h, vn);
}

// The new state of free mass k, projected onto its anchored stick and counted if not finite.
fn write_state(k: u32, m: PhysicsMass, x: vec3<f32>, v: vec3<f32>) {
    var xn = x;
    var vn = v;
    if steps[si].flags.y != 0u && m.stick_parent != NO_LINK {
        project_on_stick(m, &xn, &vn);
    }
    if !(finite3(xn) && finite3(vn)) {
        count(0u);
    }
    x_out[k] = vec4<f32>(xn, 0.0);
    v_out[k] = vec4<f32>(vn, 0.0);
}

// XPBD (crates/sim/src/solvers/xpbd.rs), one step of one pack in one workgroup: the
// multipliers to zero; 1. predict the displacement h (v + Δv) under the external and restoring
// forces at the step's start (the restoring stiffness 2w/L on the diagonal), kept in v_out;
// 2. `iterations` symmetric Gauss–Seidel sweeps, colour by colour up and back down, each colour's
// links projected in parallel (within a colour no free mass has two links) with a barrier
// between colours; 3. the new state x + Δx, velocity Δx/h and the stick projection. The same
// arithmetic in the same colour order as the CPU's sweep, so one dispatch replaces a dispatch per
// colour.
const XPBD_THREADS: u32 = 256u;

struct PhysicsXpbdLink {
    a: u32,
    b: u32,
    rest: f32,
    // 1/k: 0 for a stick, +inf for a link without stiffness
    compliance: f32,
    c: f32,
    wa: f32,
    wb: f32,
    pad0: f32,
}

struct PhysicsColours {
    // colours, iterations, links, unused
    count: vec4<u32>,
    // colour c's links start at starts[c / 4][c % 4] (colours + 1 entries)
    starts: array<vec4<u32>, 16>,
}

@group(0) @binding(10) var<storage, read> xpbd_links: array<PhysicsXpbdLink>;
// per link: the damper's multiplier (xyz) and the distance multiplier (w)
@group(0) @binding(11) var<storage, read_write> xpbd_lambda: array<vec4<f32>>;
@group(0) @binding(12) var<uniform> xpbd_colours: PhysicsColours;

// Where colour c's links start in the herd's XPBD links, for this pack.
fn colour_start(c: u32) -> u32 {
    return steps[si].base2.x + xpbd_colours.starts[c / 4u][c % 4u];
}

// One link projected (distance, then damper) on the displacements in v_out.
fn xpbd_link(i: u32, h: f32) {
    let l = xpbd_links[i];
    // An anchored end has zero inverse mass.
    let free_b = l.wb != 0.0;
    var da = v_out[l.a].xyz;
    var db = vec3<f32>(0.0);
    if free_b {
        db = v_out[l.b].xyz;
    }
    var lam = xpbd_lambda[i];
    if l.compliance <= 3.4028235e38 {
        let at = l.compliance / (h * h);
        let den = l.wa + l.wb + at;
        let d = (x_in[l.a].xyz - x_in[l.b].xyz) + (da - db);
        let len = length(d);
        if len > 1e-12 {
            let n = d / len;
            let dl = (-(len - l.rest) - at * lam.w) / den;
            lam.w = lam.w + dl;
            da = da + n * (l.wa * dl);
            db = db - n * (l.wb * dl);
        }
    }
    if l.c > 0.0 {
        // An anchored end moves, for the damper, with the skin's velocity over the steps[si].
        let hc = h * l.c;
        var moved_b = v_in[l.b].xyz * h;
        if free_b {
            moved_b = db;
        }
        let dl = (-lam.xyz - (da - moved_b) * hc) / (1.0 + hc * (l.wa + l.wb));
        lam = vec4<f32>(lam.xyz + dl, lam.w);
        da = da + dl * l.wa;
        db = db - dl * l.wb;
    }
    xpbd_lambda[i] = lam;
    v_out[l.a] = vec4<f32>(da, 0.0);
    if free_b {
        v_out[l.b] = vec4<f32>(db, 0.0);
    }
}

@compute @workgroup_size(256)
fn cs_xpbd_step(@builtin(local_invocation_index) lid: u32, @builtin(workgroup_id) wid: vec3<u32>) {
    si = wid.y;
    let first = steps[si].base.x;
    let free = first + steps[si].counts.x;
    let h = steps[si].accel.w;
    let w = steps[si].alpha.w;
    for (var i = colour_start(0u) + lid; i < colour_start(0u) + xpbd_colours.count.z; i += XPBD_THREADS) {
        xpbd_lambda[i] = vec4<f32>(0.0);
    }
    for (var k = first + lid; k < free; k += XPBD_THREADS) {
        let m = masses[k];
        let xi = x_in[k].xyz;
        let vi = v_in[k].xyz;
        let f = external_force(m, xi, vi) + restoring_force(m, xi);
        var kr = 0.0;
        var vp = vec3<f32>(0.0);
        if m.restoring_parent != NO_LINK && w != 0.0 {
            kr = 2.0 * w / max(m.restoring_n.w, 1e-3);
            vp = v_in[m.restoring_parent].xyz;
        }
        let dv = (f - (vi - vp) * (h * kr)) * (h / (m.mass + h * h * kr));
        v_out[k] = vec4<f32>((vi + dv) * h, 0.0);
    }
    storageBarrier();
    let colours = xpbd_colours.count.x;
    if colours > 0u {
        for (var it = 0u; it < xpbd_colours.count.y; it++) {
            for (var s = 0u; s < 2u * colours - 1u; s++) {
                // Out along the hairs, then back.
                let c = select(2u * colours - 2u - s, s, s < colours);
                for (var i = colour_start(c) + lid; i < colour_start(c + 1u); i += XPBD_THREADS) {
                    xpbd_link(i, h);
                }
                storageBarrier();
            }
        }
    }
    for (var k = first + lid; k < free; k += XPBD_THREADS) {
        let d = v_out[k].xyz;
        write_state(k, masses[k], x_in[k].xyz + d, d * (1.0 / h));
    }
}

// A teleport at the start of a step (crates/sim/src/simulator.rs `teleport`): the mesh frame
// jumps by `teleport` and the free masses keep their world positions, so in the mesh frame they
// move by −teleport; rigid links snap back onto their anchored parents. In place on the current
// state (bindings 3 and 4 of the final-state group).
@compute @workgroup_size(64)
fn cs_teleport(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    if gid.x >= steps[si].counts.x {
        return;
    }
    if steps[si].teleport.w == 0.0 {
        return;
    }
    let k = steps[si].base.x + gid.x;
    var x = x_out[k].xyz - steps[si].teleport.xyz;
    var v = v_out[k].xyz;
    let m = masses[k];
    if steps[si].flags.y != 0u && m.stick_parent != NO_LINK {
        project_on_stick(m, &x, &v);
    }
    x_out[k] = vec4<f32>(x, 0.0);
    v_out[k] = vec4<f32>(v, 0.0);
}

// The guard's pass over the tips, after the last substep (bindings of group 1).
@group(1) @binding(0) var<storage, read> tips: array<PhysicsTip>;
// per tip: the scale vector (xyz) and frozen (w = 1)
@group(1) @binding(1) var<storage, read_write> guard_state: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read> shell_tip: array<u32>;
// the renderer's scale vectors, one per shell vertex (xyz; w unused)
@group(1) @binding(3) var<storage, read_write> scale_out: array<vec4<f32>>;

// The wrong-side guard of §3.4.3 on one tip of the state in x_out, v_out: a scale vector more than
// the guard's angle from its rest direction freezes at its last good value and kicks the tip out
// along the normal once; otherwise it follows the masses (crates/sim/src/shell.rs).
@compute @workgroup_size(64)
fn cs_guard(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    if gid.x >= steps[si].counts.y {
        return;
    }
    let i = steps[si].base.z + gid.x;
    let t = tips[i];
    let e = x_out[t.tip].xyz - t.root_pos.xyz;
    let rcp = 1.0 / sqrt(dot(e, e));
    let ok = rcp > 0.0 && rcp <= 3.4028235e38;
    let sn = e * rcp;
    let n = t.n.xyz;
    var state = guard_state[i];
    if steps[si].guard.z == 0.0 {
        state = vec4<f32>(select(n, sn, ok), 0.0);
    } else if ok && dot(n, sn) >= steps[si].guard.x {
        state = vec4<f32>(sn, 0.0);
    } else if state.w == 0.0 {
        state.w = 1.0;
        v_out[t.tip] = vec4<f32>(v_out[t.tip].xyz + steps[si].guard.y * n, 0.0);
        count(1u);
    }
    if state.w != 0.0 {
        count(2u);
    }
    guard_state[i] = state;
}

// Scale vectors per shell vertex from the guarded tips. A bare vertex (no tip) keeps what the
// buffer holds, its rest direction: only bare triangles use it, and they draw no fur.
@compute @workgroup_size(64)
fn cs_scale(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    let i = gid.x;
    if i >= steps[si].counts.z {
        return;
    }
    let s = shell_tip[i];
    if s != NO_LINK {
        scale_out[steps[si].base.w + i] = vec4<f32>(guard_state[steps[si].base.z + s].xyz, 0.0);
    }
}

// ---- The skin moves (crates/sim/src/skin.rs; the bind pose of crates/sim/src/compute.rs) ----
// Before a step on an animated skin, five passes pose the model as `BindPose::pose` does: every
// mass's rest position through the transform of the shell vertex it hangs from and the fastest
// anchor's speed (cs_pose_rest); free masses' rest positions and directions, carried along on a
// cut, back onto their anchored sticks (cs_pose_free); anchored masses to their posed positions
// with the jump's velocity (cs_pose_anchored); tips' rest directions and roots, and the guard's
// scale vectors past its angle reset (cs_pose_tips); links between hairs keeping their bind
// strain (cs_pose_between).

struct PoseTransform {
    // the blended skinning matrix's columns (xyz); the w of the first three: the morph offset (m)
    c0: vec4<f32>,
    c1: vec4<f32>,
    c2: vec4<f32>,
    c3: vec4<f32>,
    // the normal matrix's columns (xyz)
    n0: vec4<f32>,
    n1: vec4<f32>,
    n2: vec4<f32>,
}

struct PoseMass {
    // the bind rest position (xyz)
    rest: vec4<f32>,
    // the restoring link's bind rest direction (xyz; free masses)
    n: vec4<f32>,
    // the shell vertex it hangs from, or NO_LINK (it keeps its bind pose)
    attach: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct PoseBetween {
    a: u32,
    b: u32,
    // the link entries holding its rest length from either free end, or NO_LINK
    e0: u32,
    e1: u32,
    rest: f32,
    bind_distance: f32,
    // its XPBD link, or NO_LINK
    xpbd: u32,
    pad0: u32,
}

@group(0) @binding(21) var<storage, read> pose_transforms: array<PoseTransform>;
@group(0) @binding(22) var<storage, read> pose_masses: array<PoseMass>;
@group(0) @binding(23) var<storage, read_write> posed: array<vec4<f32>>;
// per step of a record: the fastest anchor's speed (m/s, as bits)
@group(0) @binding(24) var<storage, read_write> pose_speed: array<atomic<u32>>;
// the current state, and the other state buffer (anchored masses are in both)
@group(0) @binding(25) var<storage, read_write> pose_x: array<vec4<f32>>;
@group(0) @binding(26) var<storage, read_write> pose_v: array<vec4<f32>>;
@group(0) @binding(27) var<storage, read_write> pose_x_other: array<vec4<f32>>;
@group(0) @binding(28) var<storage, read_write> pose_v_other: array<vec4<f32>>;
@group(0) @binding(29) var<storage, read_write> pose_physics: array<PhysicsMass>;
@group(0) @binding(30) var<storage, read_write> pose_tips: array<PhysicsTip>;
@group(0) @binding(31) var<storage, read_write> pose_guard: array<vec4<f32>>;
// per tip: its bind rest direction (xyz)
@group(0) @binding(32) var<storage, read> pose_tip_n: array<vec4<f32>>;
@group(0) @binding(33) var<storage, read> pose_between: array<PoseBetween>;
@group(0) @binding(34) var<storage, read_write> pose_links: array<PhysicsLink>;
@group(0) @binding(35) var<storage, read_write> pose_xpbd_links: array<PhysicsXpbdLink>;

// A bind-pose position through shell vertex s's transform: `matrix · (p + morph)`.
fn pose_point(s: u32, p: vec3<f32>) -> vec3<f32> {
    if s == NO_LINK {
        return p;
    }
    let t = pose_transforms[steps[si].pose_at.x + s];
    let q = p + vec3<f32>(t.c0.w, t.c1.w, t.c2.w);
    return t.c0.xyz * q.x + t.c1.xyz * q.y + t.c2.xyz * q.z + t.c3.xyz;
}

// A bind-pose direction through shell vertex s's normal matrix, unit (the bind direction where
// that has no length).
fn pose_direction(s: u32, n: vec3<f32>) -> vec3<f32> {
    if s == NO_LINK {
        return n;
    }
    let t = pose_transforms[steps[si].pose_at.x + s];
    let d = t.n0.xyz * n.x + t.n1.xyz * n.y + t.n2.xyz * n.z;
    let rcp = 1.0 / length(d);
    if rcp > 0.0 && rcp <= 3.4028235e38 {
        return d * rcp;
    }
    return n;
}

// The skin moved faster than the cut speed: the fur is carried along.
fn pose_cut() -> bool {
    return bitcast<f32>(atomicLoad(&pose_speed[steps[si].pose_at.y])) > steps[si].pose.y;
}

// The skin's transform per shell vertex, blended here from the step's skinning matrices and
// morph weights as the CPU's Animator blends it (crates/runtime/src/animation.rs
// vertex_transform): the morph offset Σ wₜ·Δpₜ, the matrix Σ wᵢ·Mᵢ over the vertex's influence
// slots in slot order (zero weights skipped; the identity without skin weights), and its normal
// matrix, the cofactor times the sign of the determinant (crates/sim/src/skin.rs normal_matrix).
@group(0) @binding(50) var<storage, read> blend_binds: array<u32>;
@group(0) @binding(51) var<storage, read> blend_weights: array<f32>;
@group(0) @binding(52) var<storage, read> blend_deltas: array<f32>;
@group(0) @binding(53) var<storage, read> blend_matrices: array<mat4x4<f32>>;
@group(0) @binding(54) var<storage, read> blend_morph_weights: array<f32>;
// per shell vertex: its welded skin vertex
@group(0) @binding(55) var<storage, read> blend_shell_vertices: array<u32>;
@group(0) @binding(56) var<storage, read_write> blend_out: array<PoseTransform>;

@compute @workgroup_size(64)
fn cs_pose_blend(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    let s = gid.x;
    if s >= steps[si].counts.z || steps[si].pose.w == 0.0 {
        return;
    }
    let v = blend_shell_vertices[s];
    let per = steps[si].pose_skin.z & 0xffu;
    let targets = steps[si].pose_skin.z >> 8u;
    let skin_vertices = steps[si].pose_skin.w;
    var offset = vec3<f32>(0.0);
    for (var t = 0u; t < targets; t++) {
        let w = blend_morph_weights[steps[si].pose_skin.y + t];
        if w != 0.0 {
            let i = 3u * (t * skin_vertices + v);
            offset = offset + w * vec3<f32>(blend_deltas[i], blend_deltas[i + 1u], blend_deltas[i + 2u]);
        }
    }
    var m = mat4x4<f32>(vec4<f32>(1.0, 0.0, 0.0, 0.0), vec4<f32>(0.0, 1.0, 0.0, 0.0), vec4<f32>(0.0, 0.0, 1.0, 0.0), vec4<f32>(0.0, 0.0, 0.0, 1.0));
    if per > 0u {
        m = mat4x4<f32>();
        let first = v * per;
        for (var k = 0u; k < per; k++) {
            let w = blend_weights[first + k];
            if w != 0.0 {
                let slot = first + k;
                let bind = (blend_binds[slot >> 1u] >> ((slot & 1u) * 16u)) & 0xffffu;
                m = m + blend_matrices[steps[si].pose_skin.x + bind] * w;
            }
        }
    }
    let c0 = m[0].xyz;
    let c1 = m[1].xyz;
    let c2 = m[2].xyz;
    let sign = select(1.0, -1.0, dot(c0, cross(c1, c2)) < 0.0);
    blend_out[steps[si].pose_at.x + s] = PoseTransform(
        vec4<f32>(c0, offset.x),
        vec4<f32>(c1, offset.y),
        vec4<f32>(c2, offset.z),
        vec4<f32>(m[3].xyz, 0.0),
        vec4<f32>(cross(c1, c2) * sign, 0.0),
        vec4<f32>(cross(c2, c0) * sign, 0.0),
        vec4<f32>(cross(c0, c1) * sign, 0.0),
    );
}

@compute @workgroup_size(64)
fn cs_pose_rest(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    let k = gid.x;
    if k >= steps[si].pose_at.z || steps[si].pose.z == 0.0 {
        return;
    }
    let pm = pose_masses[k];
    let p = pose_point(pm.attach, pm.rest.xyz);
    let g = steps[si].base.x + k;
    posed[g] = vec4<f32>(p, 0.0);
    if k >= steps[si].counts.x {
        // Non-negative floats order as their bits; a NaN (above +inf's bits) is skipped, as the
        // CPU's maximum skips it.
        let bits = bitcast<u32>(length(p - pose_x[g].xyz) * steps[si].pose.x);
        if bits <= 0x7f800000u {
            atomicMax(&pose_speed[steps[si].pose_at.y], bits);
        }
    }
}

@compute @workgroup_size(64)
fn cs_pose_free(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    if gid.x >= steps[si].counts.x || steps[si].pose.z == 0.0 {
        return;
    }
    let k = steps[si].base.x + gid.x;
    var m = pose_physics[k];
    let pm = pose_masses[gid.x];
    let p = posed[k].xyz;
    var x = pose_x[k].xyz;
    var v = pose_v[k].xyz;
    if pose_cut() {
        x = x + (p - m.rest_pos.xyz);
    }
    m.rest_pos = vec4<f32>(p, 0.0);
    m.restoring_n = vec4<f32>(pose_direction(pm.attach, pm.n.xyz), m.restoring_n.w);
    if m.stick_parent != NO_LINK {
        m.stick_anchor = vec4<f32>(posed[m.stick_parent].xyz, 0.0);
        if steps[si].flags.y != 0u {
            project_on_stick(m, &x, &v);
        }
    }
    pose_physics[k] = m;
    pose_x[k] = vec4<f32>(x, 0.0);
    pose_v[k] = vec4<f32>(v, 0.0);
}

@compute @workgroup_size(64)
fn cs_pose_anchored(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    if steps[si].counts.x + gid.x >= steps[si].pose_at.z || steps[si].pose.z == 0.0 {
        return;
    }
    let k = steps[si].base.x + steps[si].counts.x + gid.x;
    let p = posed[k].xyz;
    var vel = vec3<f32>(0.0);
    if !pose_cut() {
        vel = (p - pose_x[k].xyz) * steps[si].pose.x;
    }
    pose_x[k] = vec4<f32>(p, 0.0);
    pose_x_other[k] = vec4<f32>(p, 0.0);
    pose_v[k] = vec4<f32>(vel, 0.0);
    pose_v_other[k] = vec4<f32>(vel, 0.0);
}

@compute @workgroup_size(64)
fn cs_pose_tips(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    if gid.x >= steps[si].counts.y || steps[si].pose.z == 0.0 {
        return;
    }
    let i = steps[si].base.z + gid.x;
    var t = pose_tips[i];
    let n = pose_direction(pose_masses[t.tip - steps[si].base.x].attach, pose_tip_n[gid.x].xyz);
    t.n = vec4<f32>(n, 0.0);
    t.root_pos = vec4<f32>(posed[t.root].xyz, 0.0);
    pose_tips[i] = t;
    // A scale vector now past the guard's angle from its rest direction starts again from it
    // (crates/sim/src/shell.rs follow_rest_directions).
    var cos_a = -1.0;
    if steps[si].guard.z != 0.0 {
        cos_a = steps[si].guard.x;
    }
    let g = pose_guard[i];
    if dot(n, g.xyz) < cos_a {
        pose_guard[i] = vec4<f32>(n, g.w);
    }
}

@compute @workgroup_size(64)
fn cs_pose_between(@builtin(global_invocation_id) gid: vec3<u32>) {
    si = gid.y;
    let i = gid.x;
    if i >= steps[si].pose_at.w || steps[si].pose.z == 0.0 {
        return;
    }
    let b = pose_between[i];
    let base = steps[si].base;
    var rest = b.rest;
    if b.bind_distance > 0.0 {
        rest = b.rest * (distance(posed[base.x + b.a].xyz, posed[base.x + b.b].xyz) / b.bind_distance);
    }
    if b.e0 != NO_LINK {
        pose_links[base.y + b.e0].rest = rest;
    }
    if b.e1 != NO_LINK {
        pose_links[base.y + b.e1].rest = rest;
    }
    if b.xpbd != NO_LINK {
        pose_xpbd_links[steps[si].base2.x + b.xpbd].rest = rest;
    }
}

// ---- Energy, on request (crates/sim/src/simulator.rs `energy`) ----
// Per free mass: ½ m v², its links' ½ k (l − l₀)² (halved for a link to another free mass, which
// lists it too), and the restoring link's ½ w L (1 − n·s)²; summed per workgroup in f32 and
// written as one partial sum each, which the host adds up in f64 once it reads them back.
const ENERGY_THREADS: u32 = 256u;

@group(0) @binding(40) var<storage, read> energy_x: array<vec4<f32>>;
@group(0) @binding(41) var<storage, read> energy_v: array<vec4<f32>>;
@group(0) @binding(42) var<storage, read> energy_masses: array<PhysicsMass>;
@group(0) @binding(43) var<storage, read> energy_links: array<PhysicsLink>;
// Per workgroup: kinetic, spring, restoring energy (J), unused.
@group(0) @binding(44) var<storage, read_write> energy_partials: array<vec4<f32>>;

var<workgroup> energy_sums: array<vec4<f32>, 256>;

@compute @workgroup_size(256)
fn cs_energy(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    // One pack per y (its own uniforms at si, its partial sums after the earlier packs').
    si = wid.y;
    let k = steps[si].base.x + gid.x;
    var e = vec4<f32>(0.0);
    if gid.x < steps[si].counts.x {
        let m = energy_masses[k];
        let xi = energy_x[k].xyz;
        let vi = energy_v[k].xyz;
        e.x = 0.5 * m.mass * dot(vi, vi);
        for (var i = m.links_start; i < m.links_end; i++) {
            let l = energy_links[i];
            let stretch = length(energy_x[l.other].xyz - xi) - l.rest;
            let share = select(1.0, 0.5, l.other < steps[si].base.x + steps[si].counts.x);
            e.y += share * 0.5 * l.k * stretch * stretch;
        }
        let w = steps[si].alpha.w;
        if m.restoring_parent != NO_LINK {
            let s = xi - energy_x[m.restoring_parent].xyz;
            let len = length(s);
            var c = 1.0;
            if len > 0.0 {
                c = 1.0 - dot(m.restoring_n.xyz, s / len);
            }
            e.z = 0.5 * w * m.restoring_n.w * c * c;
        }
    }
    energy_sums[lid] = e;
    workgroupBarrier();
    for (var half = ENERGY_THREADS / 2u; half > 0u; half >>= 1u) {
        if lid < half {
            energy_sums[lid] += energy_sums[lid + half];
        }
        workgroupBarrier();
    }
    if lid == 0u {
        energy_partials[steps[si].base2.y * groups.x + wid.x] = energy_sums[0];
    }
}
