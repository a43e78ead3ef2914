//! An animated skin's pose on the GPU: the bind pose of a [`furbake_sim::ComputeModel`]
//! ([`furbake_sim::ComputePose`]), each posed step's [`SkinTransform`]s uploaded with the step's
//! uniforms or blended here from its skinning matrices (`cs_pose_blend`), and the five passes of `shaders/fur_physics.wgsl` that pose the model
//! before the step as furbake-sim's `skin.rs` does (docs/design.md, "Fur physics on the GPU").

use furbake_sim::{ComputeModel, NO_LINK, SkinTransform};
use wgpu::util::DeviceExt;

use super::{GpuPose, GpuSkin, WORKGROUP, dynamic_steps, entry, layout_entry, pad, steps_entry, storage_binding};
use crate::RenderError;
use crate::skinning::SkinInputs;

/// One shell vertex's transform (`PoseTransform` in `fur_physics.wgsl`): the skinning matrix's
/// columns with the morph offset in the first three `w`s, then the normal matrix's columns.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PoseTransform {
    c0: [f32; 4],
    c1: [f32; 4],
    c2: [f32; 4],
    c3: [f32; 4],
    n0: [f32; 4],
    n1: [f32; 4],
    n2: [f32; 4],
}

impl PoseTransform {
    fn of(t: &SkinTransform) -> PoseTransform {
        let (m, n, o) = (&t.matrix, &t.normal_matrix, t.morph_offset_m);
        let c = |v: glam::Vec4, w: f32| [v.x, v.y, v.z, w];
        let d = |v: glam::Vec3| [v.x, v.y, v.z, 0.0];
        PoseTransform {
            c0: c(m.x_axis, o.x),
            c1: c(m.y_axis, o.y),
            c2: c(m.z_axis, o.z),
            c3: c(m.w_axis, 0.0),
            n0: d(n.x_axis),
            n1: d(n.y_axis),
            n2: d(n.z_axis),
        }
    }
}

/// One mass's bind pose (`PoseMass`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PoseMass {
    rest: [f32; 4],
    n: [f32; 4],
    attach: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

/// One link between hairs (`PoseBetween`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PoseBetween {
    a: u32,
    b: u32,
    e0: u32,
    e1: u32,
    rest: f32,
    bind_distance: f32,
    xpbd: u32,
    pad0: u32,
}

/// The buffers of the physics a pose writes (bound into the pose passes' groups).
pub(super) struct PoseTargets<'a> {
    pub steps: &'a wgpu::Buffer,
    pub x: &'a [wgpu::Buffer; 2],
    pub v: &'a [wgpu::Buffer; 2],
    pub masses: &'a wgpu::Buffer,
    pub links: &'a wgpu::Buffer,
    pub tips: &'a wgpu::Buffer,
    pub guard: &'a wgpu::Buffer,
}

/// The passes, in order: the blend (only for a pose given as skinning matrices), then the five
/// that pose the model.
const PASSES: [&str; 6] =
    ["cs_pose_blend", "cs_pose_rest", "cs_pose_free", "cs_pose_anchored", "cs_pose_tips", "cs_pose_between"];

/// The bindings of each pass (besides the step uniforms at 0), and whether each is read-only.
const BINDINGS: [&[(u32, bool)]; 6] = [
    &[(50, true), (51, true), (52, true), (53, true), (54, true), (55, true), (56, false)],
    &[(21, true), (22, true), (23, false), (24, false), (25, false)],
    &[(21, true), (22, true), (23, false), (24, false), (25, false), (26, false), (29, false)],
    &[(23, false), (24, false), (25, false), (26, false), (27, false), (28, false)],
    &[(21, true), (22, true), (23, false), (30, false), (31, false), (32, true)],
    &[(23, false), (33, true), (34, false), (35, false)],
];

/// A pack's pose on the GPU.
pub(super) struct Pose {
    /// Shell vertices, masses, free masses, tips, links between hairs.
    shell: u32,
    masses: u32,
    free: u32,
    tips: u32,
    between: u32,
    transforms: wgpu::Buffer,
    /// Poses the transforms buffer holds.
    transforms_capacity: u32,
    /// Per step of a record, the fastest anchor's speed.
    speed: wgpu::Buffer,
    speed_capacity: u32,
    pose_masses: wgpu::Buffer,
    posed: wgpu::Buffer,
    tip_n: wgpu::Buffer,
    between_buffer: wgpu::Buffer,
    /// XPBD's links (a one-link stand-in for the other solvers).
    xpbd_links: wgpu::Buffer,
    /// The skin's influences for poses given as skinning matrices (an animated asset's).
    skin: Option<SkinInputs>,
    /// Per posed step of a record: its skinning matrices and morph weights (grow-only).
    matrices: wgpu::Buffer,
    morph_weights: wgpu::Buffer,
    /// One record's matrices and morph weights as bytes, reused.
    matrix_bytes: Vec<u8>,
    weight_bytes: Vec<u8>,
    layouts: Vec<wgpu::BindGroupLayout>,
    pipelines: Vec<wgpu::ComputePipeline>,
    /// Per pass, a group per current state buffer (the same group twice for passes that do not
    /// touch the state).
    groups: Vec<[wgpu::BindGroup; 2]>,
    /// One record's transforms as bytes, reused.
    bytes: Vec<u8>,
}

impl Pose {
    /// The pose of `packs` packs of `model` (which has a bind pose), or `None` for a static skin.
    pub fn new(
        device: &wgpu::Device,
        model: &ComputeModel,
        packs: u32,
        module: &wgpu::ShaderModule,
        targets: &PoseTargets<'_>,
        xpbd_links: Option<&wgpu::Buffer>,
        skin: Option<SkinInputs>,
    ) -> Result<Option<Pose>, RenderError> {
        let Some(bind) = &model.pose else { return Ok(None) };
        let nf = model.free as usize;
        let v4 = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
        let mut masses: Vec<PoseMass> = (0..model.masses as usize)
            .map(|k| PoseMass {
                rest: v4(bind.bind_rest[k]),
                n: if k < nf { v4(bind.bind_restoring_n[k]) } else { [0.0; 4] },
                attach: bind.attach[k],
                pad0: 0,
                pad1: 0,
                pad2: 0,
            })
            .collect();
        pad(&mut masses);
        let mut tip_n: Vec<[f32; 4]> = bind.bind_tip_n.iter().map(|&n| v4(n)).collect();
        pad(&mut tip_n);
        // An XPBD link shares its rest length with one link entry.
        let xpbd_of: std::collections::HashMap<u32, u32> =
            model.xpbd.links.iter().enumerate().map(|(i, l)| (l.entry, i as u32)).collect();
        let mut between: Vec<PoseBetween> = bind
            .between
            .iter()
            .map(|b| {
                let xpbd = b.entries.iter().find_map(|e| xpbd_of.get(e).copied()).unwrap_or(NO_LINK);
                PoseBetween {
                    a: b.ends[0],
                    b: b.ends[1],
                    e0: b.entries[0],
                    e1: b.entries[1],
                    rest: b.rest,
                    bind_distance: b.bind_distance,
                    xpbd,
                    pad0: 0,
                }
            })
            .collect();
        pad(&mut between);
        let init = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let read = wgpu::BufferUsages::STORAGE;
        let pose_masses = init("furbake physics bind pose", bytemuck::cast_slice(&masses), read);
        let tip_n = init("furbake physics bind tip directions", bytemuck::cast_slice(&tip_n), read);
        let between_buffer = init("furbake physics links between hairs", bytemuck::cast_slice(&between), read);
        let posed = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake physics posed rest positions"),
            size: masses.len() as u64 * packs as u64 * 16,
            usage: read,
            mapped_at_creation: false,
        });
        let xpbd_links = match xpbd_links {
            Some(b) => b.clone(),
            None => device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("furbake physics no xpbd links"),
                size: size_of::<super::PhysicsXpbdLink>() as u64,
                usage: read,
                mapped_at_creation: false,
            }),
        };
        let layouts: Vec<wgpu::BindGroupLayout> = BINDINGS
            .iter()
            .zip(PASSES)
            .map(|(bindings, name)| {
                let mut entries = vec![layout_entry(0, dynamic_steps())];
                entries.extend(bindings.iter().map(|&(b, read_only)| layout_entry(b, storage_binding(read_only))));
                device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(name), entries: &entries })
            })
            .collect();
        let pipelines = layouts
            .iter()
            .zip(PASSES)
            .map(|(layout, name)| {
                let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(name),
                    bind_group_layouts: &[Some(layout)],
                    immediate_size: 0,
                });
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(name),
                    layout: Some(&pipeline_layout),
                    module,
                    entry_point: Some(name),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
            .collect();
        let (transforms, speed) =
            (transform_buffer(device, 1, model.shell_tip.len() as u32), speed_buffer(device, 4 * packs));
        let (binds, targets_n) = skin.as_ref().map_or((0, 0), |s| (s.bind_count, s.target_count));
        let mut pose = Pose {
            matrices: skin_buffer(device, "furbake physics skinning matrices", binds as u64 * 64),
            morph_weights: skin_buffer(device, "furbake physics morph weights", targets_n as u64 * 4),
            skin,
            matrix_bytes: Vec::new(),
            weight_bytes: Vec::new(),
            shell: model.shell_tip.len() as u32,
            masses: model.masses,
            free: model.free,
            tips: model.tips.len() as u32,
            between: bind.between.len() as u32,
            transforms,
            transforms_capacity: 1,
            speed,
            speed_capacity: 4 * packs,
            pose_masses,
            posed,
            tip_n,
            between_buffer,
            xpbd_links,
            layouts,
            pipelines,
            groups: Vec::new(),
            bytes: Vec::new(),
        };
        pose.rebind(device, targets);
        Ok(Some(pose))
    }

    /// Checks one step's pose: a transform per shell vertex, all finite, a cut speed.
    pub fn check(&self, pose: &GpuPose<'_>) -> Result<(), RenderError> {
        let bad = |what: String| Err(RenderError::Parameter { what });
        match pose.skin {
            GpuSkin::Transforms(transforms) => {
                if transforms.len() != self.shell as usize {
                    return bad(format!("{} skin transforms for {} shell vertices", transforms.len(), self.shell));
                }
                if let Some(s) = transforms.iter().position(|t| {
                    !(t.matrix.is_finite() && t.normal_matrix.is_finite() && t.morph_offset_m.is_finite())
                }) {
                    return bad(format!("the skin transform of shell vertex {s} is not finite"));
                }
            }
            GpuSkin::Skinning { matrices, morph_weights } => {
                let Some(skin) = &self.skin else {
                    return bad("skinning matrices for GPU physics of a renderer without a skin".into());
                };
                if matrices.len() != skin.bind_count as usize || morph_weights.len() != skin.target_count as usize {
                    return bad(format!(
                        "{} skinning matrices and {} morph weights for a skin of {} binds and {} targets",
                        matrices.len(),
                        morph_weights.len(),
                        skin.bind_count,
                        skin.target_count
                    ));
                }
                if !(matrices.iter().all(|m| m.is_finite()) && morph_weights.iter().all(|w| w.is_finite())) {
                    return bad("a skinning matrix or morph weight is not finite".into());
                }
            }
        }
        if pose.cut_speed_m_per_s.is_nan() || pose.cut_speed_m_per_s < 0.0 {
            return bad(format!("cut speed {} m/s (must be zero or more)", pose.cut_speed_m_per_s));
        }
        Ok(())
    }

    /// Makes room for `transforms` slots of skin transforms, `poses` poses' skinning matrices and
    /// `steps` speed slots (one per pack and step; grows, never shrinks: a steady frame rate
    /// allocates nothing here); true when the buffers were replaced and the groups must be bound
    /// again. More than one storage binding holds is a [`RenderError::Parameter`], before
    /// anything is replaced.
    pub fn reserve(
        &mut self,
        device: &wgpu::Device,
        transforms: u32,
        poses: u32,
        steps: u32,
    ) -> Result<bool, RenderError> {
        let limits = device.limits();
        let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let (binds, targets) = self.skin.as_ref().map_or((0, 0), |s| (s.bind_count as u64, s.target_count as u64));
        let needed = [
            ("skin transforms", transforms as u64 * self.shell as u64 * size_of::<PoseTransform>() as u64),
            ("skinning matrices", poses as u64 * binds * 64),
            ("morph weights", poses as u64 * targets * 4),
        ];
        if let Some((what, bytes)) = needed.iter().find(|(_, b)| *b > limit) {
            return Err(RenderError::Parameter {
                what: format!(
                    "one record's {what} take {bytes} bytes, more than the device's storage binding of {limit}: \
                     record fewer steps or packs at once"
                ),
            });
        }
        let mut grown = false;
        if transforms > self.transforms_capacity {
            // Doubles, up to what one binding holds.
            let capacity = transforms.next_power_of_two();
            let fits = (limit / (self.shell.max(1) as u64 * size_of::<PoseTransform>() as u64)) as u32;
            self.transforms_capacity = capacity.min(fits.max(transforms));
            self.transforms = transform_buffer(device, self.transforms_capacity, self.shell);
            grown = true;
        }
        if steps > self.speed_capacity {
            self.speed_capacity = steps.next_power_of_two();
            self.speed = speed_buffer(device, self.speed_capacity);
            grown = true;
        }
        if self.skin.is_some() {
            let (m, w) = (needed[1].1, needed[2].1);
            if m > self.matrices.size() {
                let bytes = m.next_power_of_two().min(limit).max(m);
                self.matrices = skin_buffer(device, "furbake physics skinning matrices", bytes);
                grown = true;
            }
            if w > self.morph_weights.size() {
                let bytes = w.next_power_of_two().min(limit).max(w);
                self.morph_weights = skin_buffer(device, "furbake physics morph weights", bytes);
                grown = true;
            }
        }
        Ok(grown)
    }

    /// Binds the pose passes to the physics' buffers (again after any of them was replaced).
    pub fn rebind(&mut self, device: &wgpu::Device, t: &PoseTargets<'_>) {
        let buffer = |b: u32, at: usize| -> &wgpu::Buffer {
            match b {
                21 => &self.transforms,
                22 => &self.pose_masses,
                23 => &self.posed,
                24 => &self.speed,
                25 => &t.x[at],
                26 => &t.v[at],
                27 => &t.x[1 - at],
                28 => &t.v[1 - at],
                29 => t.masses,
                30 => t.tips,
                31 => t.guard,
                32 => &self.tip_n,
                33 => &self.between_buffer,
                34 => t.links,
                35 => &self.xpbd_links,
                50 => self.skin.as_ref().map_or(&self.posed, |s| &s.binds),
                51 => self.skin.as_ref().map_or(&self.posed, |s| &s.weights),
                52 => self.skin.as_ref().map_or(&self.posed, |s| &s.deltas),
                53 => &self.matrices,
                54 => &self.morph_weights,
                55 => self.skin.as_ref().map_or(&self.posed, |s| &s.shell_vertices),
                _ => &self.transforms,
            }
        };
        self.groups = BINDINGS
            .iter()
            .zip(&self.layouts)
            .zip(PASSES)
            .map(|((bindings, layout), name)| {
                [0, 1].map(|at| {
                    let mut entries = vec![steps_entry(t.steps)];
                    entries.extend(bindings.iter().map(|&(b, _)| entry(b, buffer(b, at))));
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some(name),
                        layout,
                        entries: &entries,
                    })
                })
            })
            .collect();
    }

    /// Uploads the transforms and skinning matrices of a record's poses, in order (staged until
    /// the host's next submission, as the step uniforms are): the k-th pose's matrices into slot
    /// k, the k-th pose given as transforms into transform slot k (the slots
    /// [`Pose::uniforms`] was given).
    pub fn write<'p>(&mut self, queue: &wgpu::Queue, poses: impl Iterator<Item = GpuPose<'p>>) {
        self.matrix_bytes.clear();
        self.weight_bytes.clear();
        let (binds, targets) = self.skin.as_ref().map_or((0, 0), |s| (s.bind_count as usize, s.target_count as usize));
        let mut slot = 0u64;
        for (k, p) in poses.enumerate() {
            match p.skin {
                GpuSkin::Transforms(transforms) => {
                    // This pose's slot of the transforms (a blended pose's slot is written by
                    // cs_pose_blend).
                    self.bytes.clear();
                    for t in transforms {
                        self.bytes.extend_from_slice(bytemuck::bytes_of(&PoseTransform::of(t)));
                    }
                    let at = slot * self.shell as u64 * size_of::<PoseTransform>() as u64;
                    queue.write_buffer(&self.transforms, at, &self.bytes);
                    slot += 1;
                }
                GpuSkin::Skinning { matrices, morph_weights } => {
                    // Slot k of the matrices and weights (the uniforms point there).
                    self.matrix_bytes.resize(k * binds * 64, 0);
                    self.weight_bytes.resize(k * targets * 4, 0);
                    for m in matrices {
                        self.matrix_bytes.extend_from_slice(bytemuck::bytes_of(&m.to_cols_array()));
                    }
                    self.weight_bytes.extend_from_slice(bytemuck::cast_slice(morph_weights));
                }
            }
        }
        if !self.matrix_bytes.is_empty() {
            queue.write_buffer(&self.matrices, 0, &self.matrix_bytes);
        }
        if !self.weight_bytes.is_empty() {
            queue.write_buffer(&self.morph_weights, 0, &self.weight_bytes);
        }
    }

    /// Zeroes the speeds of the coming record (outside any pass).
    pub fn clear(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.clear_buffer(&self.speed, 0, None);
    }

    /// The uniforms' pose fields for the record's `posed`-th pose (counted step by step, pack by
    /// pack; its skinning matrices' slot), whose skin transforms are in slot `transforms` and
    /// whose fastest anchor goes to speed slot `speed`, applied before a step of `dt_s` seconds;
    /// `blend` where it is given as skinning matrices.
    pub fn uniforms(
        &self,
        posed: u32,
        transforms: u32,
        speed: u32,
        dt_s: f64,
        cut_speed_m_per_s: f32,
        blend: bool,
    ) -> ([f32; 4], [u32; 4], [u32; 4]) {
        let skin = self.skin.as_ref().map_or([0; 4], |s| {
            [
                posed * s.bind_count,
                posed * s.target_count,
                s.influences_per_vertex | s.target_count << 8,
                s.vertex_count,
            ]
        });
        (
            [(1.0 / dt_s) as f32, cut_speed_m_per_s, 1.0, if blend { 1.0 } else { 0.0 }],
            [transforms * self.shell, speed, self.masses, self.between],
            skin,
        )
    }

    /// Records the passes for `packs` packs with the step uniforms at `offset`, the state in
    /// buffers `current`: with `blend`, the transforms blended from the step's skinning matrices
    /// first (for the packs whose pose is given so). A pack not posed in this step skips them.
    pub fn record(&self, pass: &mut wgpu::ComputePass<'_>, offset: u32, current: usize, blend: bool, packs: u32) {
        let shell = if blend { self.shell } else { 0 };
        let threads = [shell, self.masses, self.free, self.masses - self.free, self.tips, self.between];
        for ((pipeline, groups), n) in self.pipelines.iter().zip(&self.groups).zip(threads) {
            if n == 0 {
                continue;
            }
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &groups[current], &[offset]);
            pass.dispatch_workgroups(n.div_ceil(WORKGROUP), packs, 1);
        }
    }
}

fn transform_buffer(device: &wgpu::Device, poses: u32, shell: u32) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("furbake physics skin transforms"),
        size: (poses.max(1) as u64 * shell.max(1) as u64) * size_of::<PoseTransform>() as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A storage buffer the host writes (at least 64 bytes: bindings cannot be empty).
fn skin_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(64),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn speed_buffer(device: &wgpu::Device, steps: u32) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("furbake physics anchor speeds"),
        size: steps.max(1) as u64 * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_structs_match_the_shader() {
        use crate::shaders::tests::check_layout;
        use std::mem::offset_of;
        let t = [
            ("c0", offset_of!(PoseTransform, c0)),
            ("c1", offset_of!(PoseTransform, c1)),
            ("c2", offset_of!(PoseTransform, c2)),
            ("c3", offset_of!(PoseTransform, c3)),
            ("n0", offset_of!(PoseTransform, n0)),
            ("n1", offset_of!(PoseTransform, n1)),
            ("n2", offset_of!(PoseTransform, n2)),
        ];
        assert_eq!(check_layout("PoseTransform", size_of::<PoseTransform>(), &t), 1);
        let m = [
            ("rest", offset_of!(PoseMass, rest)),
            ("n", offset_of!(PoseMass, n)),
            ("attach", offset_of!(PoseMass, attach)),
            ("pad0", offset_of!(PoseMass, pad0)),
            ("pad1", offset_of!(PoseMass, pad1)),
            ("pad2", offset_of!(PoseMass, pad2)),
        ];
        assert_eq!(check_layout("PoseMass", size_of::<PoseMass>(), &m), 1);
        let b = [
            ("a", offset_of!(PoseBetween, a)),
            ("b", offset_of!(PoseBetween, b)),
            ("e0", offset_of!(PoseBetween, e0)),
            ("e1", offset_of!(PoseBetween, e1)),
            ("rest", offset_of!(PoseBetween, rest)),
            ("bind_distance", offset_of!(PoseBetween, bind_distance)),
            ("xpbd", offset_of!(PoseBetween, xpbd)),
            ("pad0", offset_of!(PoseBetween, pad0)),
        ];
        assert_eq!(check_layout("PoseBetween", size_of::<PoseBetween>(), &b), 1);
    }
}
