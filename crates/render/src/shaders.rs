//! The WGSL sources (in the crate's `shaders/` folder, embedded with `include_str!`) and the
//! Rust mirrors of their uniform and storage structs. The unit tests parse and validate every
//! shader with naga and check each `#[repr(C)]` struct's size and member offsets against naga's
//! layout of the WGSL struct of the same name, so the two can never drift apart silently.

/// Skin: Lambert-lit vertex colour (fur thesis §3.2), strand-shaded under fur. Like the shell and
/// fin shaders it is `lighting.wgsl` (the frame uniforms and lights), `fur_common.wgsl` (fur uniforms, effect switches, bindings 0–3 and 8,
/// `posed_vertex`, `shell_offset`, `strand_tangent`, `lambert`, `strand_shade`) followed by its
/// own file: WGSL has no includes, so the shared part
/// is prepended here.
pub const SKIN_WGSL: &str = concat!(
    include_str!("../shaders/lighting.wgsl"),
    include_str!("../shaders/fur_common.wgsl"),
    include_str!("../shaders/skin.wgsl")
);
/// Shells: extrusion, eq. 3.36 shearing, shell alpha, self-shadow, strand shading or Lambert
/// (§3.2, §3.4.2; docs/design.md "Fur shading"); also the `cs_shell_positions` compute entry
/// point that reads back the sheared shell positions and hair directions
/// ([`crate::FurRenderer::shell_positions`], [`crate::FurRenderer::shell_tangents`]).
pub const SHELL_WGSL: &str = concat!(
    include_str!("../shaders/lighting.wgsl"),
    include_str!("../shaders/fur_common.wgsl"),
    include_str!("../shaders/shell.wgsl")
);
/// Fins on fin edges (§3.2, fig. 3.16) and on the silhouette (`vs_silhouette_fin`, with the
/// structs of `silhouette_common.wgsl`).
pub const FIN_WGSL: &str = concat!(
    include_str!("../shaders/lighting.wgsl"),
    include_str!("../shaders/fur_common.wgsl"),
    include_str!("../shaders/silhouette_common.wgsl"),
    include_str!("../shaders/fin.wgsl")
);
/// The skinning pass (glTF 2.0 "Morph Targets", "Skins"): the `cs_skin` compute entry point that
/// morphs and skins every welded vertex of an animated pack once per frame
/// ([`crate::skinning::SkinningPass`]). Stands alone (no `fur_common.wgsl`).
pub const SKINNING_WGSL: &str = include_str!("../shaders/skinning.wgsl");
/// The silhouette selection (fur thesis §4.1): the `cs_silhouette` compute entry point
/// that picks the interior edges on or near this frame's silhouette for the silhouette fins
/// (`crate::silhouette`). No `fur_common.wgsl`; `silhouette_common.wgsl` (the edge and instance
/// structs the fin shader also reads) is prepended.
pub const SILHOUETTE_WGSL: &str =
    concat!(include_str!("../shaders/silhouette_common.wgsl"), include_str!("../shaders/silhouette.wgsl"));

/// Fur physics (fur thesis §3.3.2, §3.4.1–3.4.3): the `cs_step`, `cs_xpbd_step`, `cs_teleport`,
/// `cs_pose_*`, `cs_guard` and `cs_scale` compute entry points of the explicit and stick solvers,
/// XPBD, a teleport's jump, an animated skin's pose, the wrong-side guard and the scale vectors
/// ([`crate::GpuFurPhysics`]). Stands alone.
pub const FUR_PHYSICS_WGSL: &str = include_str!("../shaders/fur_physics.wgsl");

/// The hierarchical depth pyramid (grass occlusion culling): `cs_depth_copy` (level 0 from the
/// host's depth) and `cs_depth_reduce` (each further level) of [`crate::DepthPyramid`]. Stands
/// alone.
pub const DEPTH_PYRAMID_WGSL: &str = include_str!("../shaders/depth_pyramid.wgsl");

/// Grass blades (grass thesis §3.2.5–3.2.6, §4.2): the `cs_blades` compute entry point posing
/// every blade for readback and the instanced draw (`vs_blade`, `fs_blade`) from the culling
/// passes' instance lists ([`crate::blades`]). `grass_common.wgsl` (the blade instance, the
/// culling parameters, the per-blade random numbers) and `grass_pose.wgsl` (the blade's force as
/// pose-grid coordinates) are prepended.
pub const BLADES_WGSL: &str = concat!(
    include_str!("../shaders/lighting.wgsl"),
    include_str!("../shaders/grass_common.wgsl"),
    include_str!("../shaders/grass_pose.wgsl"),
    include_str!("../shaders/blades.wgsl")
);
/// The blade culling passes (grass thesis §5.3): clusters, blades, block offsets and
/// compaction into one instance list per level of detail with each drawn blade's pose-grid
/// coordinates ([`crate::culling`]), with `grass_common.wgsl` and `grass_pose.wgsl` prepended.
pub const BLADE_CULL_WGSL: &str = concat!(
    include_str!("../shaders/grass_common.wgsl"),
    include_str!("../shaders/grass_pose.wgsl"),
    include_str!("../shaders/blade_cull.wgsl")
);

pub use furbake_draw::layout::{FinVertex, FurUniforms, SurfaceVertex};

/// One light of the frame uniforms (`Light` in `shaders/lighting.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct LightUniform {
    /// Directional: unit vector from the surface towards the light, w = 0. Point: its position
    /// in world metres, w = 1.
    pub vector: [f32; 4],
    /// Colour × intensity (rgb); a point light's range in metres (a; 0 = unbounded).
    pub radiance: [f32; 4],
}

impl LightUniform {
    fn new(source: &furbake_runtime::LightSource) -> LightUniform {
        use furbake_runtime::LightSource;
        let [r, g, b] = source.radiance();
        match *source {
            LightSource::Directional { direction, .. } => {
                let to_light = -glam::Vec3::from(direction).normalize_or(glam::Vec3::NEG_Y);
                LightUniform { vector: to_light.extend(0.0).to_array(), radiance: [r, g, b, 0.0] }
            }
            LightSource::Point { position, range_m, .. } => {
                LightUniform { vector: glam::Vec3::from(position).extend(1.0).to_array(), radiance: [r, g, b, range_m] }
            }
        }
    }
}

/// Per-frame uniforms (`Frame` in `shaders/lighting.wgsl`, prepended to every drawing shader;
/// binding 0): camera, lights and the drawn object's model matrix. Built by [`FrameUniforms::new`]
/// (or [`crate::View::uniforms`]) and handed to the renderers' `prepare`, which upload it; its
/// layout is the shaders' and is not part of the API.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameUniforms {
    /// Column-major view-projection matrix (world → clip, depth in [0, 1]).
    pub(crate) view_proj: [[f32; 4]; 4],
    /// Eye position in metres (w unused).
    pub(crate) camera_pos: [f32; 4],
    /// Hemisphere ambient from above (+Y), linear RGB (a unused).
    pub(crate) ambient_sky: [f32; 4],
    /// Hemisphere ambient from below, linear RGB (a unused).
    pub(crate) ambient_ground: [f32; 4],
    /// How many of `lights` are lit (x; yzw unused).
    pub(crate) light_count: [u32; 4],
    /// The light sources; the first `light_count[0]` are lit.
    pub(crate) lights: [LightUniform; furbake_runtime::MAX_LIGHTS],
    /// Column-major model matrix of the drawn object (object/pack frame → world): rotation,
    /// translation and a uniform positive scale (normals are transformed by it too). Identity
    /// for a single object.
    pub(crate) model: [[f32; 4]; 4],
    /// The target's width and height in pixels (xy; zw unused), which the fur's level of detail
    /// measures the projected fur length in ([`FrameUniforms::with_viewport`]). Zero: not given,
    /// and the fur draws its full shell count.
    pub(crate) viewport: [f32; 4],
    /// The shell level of detail of this view (layers drawn, opacity of the layers a transition
    /// adds, continuous layer count): written by [`crate::FurRenderer::prepare`] from the other
    /// fields; whatever a host puts here is replaced.
    pub(crate) shells: [f32; 4],
}

impl FrameUniforms {
    /// The uniforms of one object drawn from a host's camera: `view_proj` (world → clip, wgpu clip
    /// space; any projection the host uses for its own geometry, reversed-Z included), the eye
    /// position in metres, what the frame is lit by (`furbake_runtime::Lighting`: up to
    /// `MAX_LIGHTS` directional and point lights and a hemisphere ambient, or the one directional
    /// `furbake_runtime::Light` of a scene's `[light]`) and the object's `model` matrix (object →
    /// world: rotation, translation, uniform positive scale). Allocates nothing.
    pub fn new(
        view_proj: glam::Mat4,
        eye: glam::Vec3,
        lighting: impl Into<furbake_runtime::Lighting>,
        model: glam::Mat4,
    ) -> Self {
        let lighting = lighting.into();
        let mut lights = [LightUniform::default(); furbake_runtime::MAX_LIGHTS];
        for (slot, source) in lights.iter_mut().zip(lighting.sources()) {
            *slot = LightUniform::new(source);
        }
        FrameUniforms {
            view_proj: view_proj.to_cols_array_2d(),
            camera_pos: [eye.x, eye.y, eye.z, 1.0],
            ambient_sky: glam::Vec3::from(lighting.ambient.sky).extend(0.0).to_array(),
            ambient_ground: glam::Vec3::from(lighting.ambient.ground).extend(0.0).to_array(),
            light_count: [lighting.sources().len() as u32, 0, 0, 0],
            lights,
            model: model.to_cols_array_2d(),
            viewport: [0.0; 4],
            shells: [0.0; 4],
        }
    }

    /// These uniforms for a target of `width` × `height` pixels (the fur's level of detail
    /// measures the projected fur length in them, docs/design.md "Shell level of detail").
    pub fn with_viewport(&self, width: u32, height: u32) -> Self {
        FrameUniforms { viewport: [width as f32, height as f32, 0.0, 0.0], ..*self }
    }

    /// These uniforms with the model matrix `model`.
    pub fn with_model(&self, model: glam::Mat4) -> Self {
        FrameUniforms { model: model.to_cols_array_2d(), ..*self }
    }

    /// The model matrix.
    pub fn model(&self) -> glam::Mat4 {
        glam::Mat4::from_cols_array_2d(&self.model)
    }

    /// The view-projection matrix (world → clip).
    pub fn view_proj(&self) -> glam::Mat4 {
        glam::Mat4::from_cols_array_2d(&self.view_proj)
    }

    /// The eye position in metres.
    pub fn eye(&self) -> glam::Vec3 {
        glam::Vec4::from(self.camera_pos).truncate()
    }

    /// The target's size in pixels (`[0, 0]` when not given: [`FrameUniforms::with_viewport`]).
    pub fn viewport(&self) -> [f32; 2] {
        [self.viewport[0], self.viewport[1]]
    }

    /// The lit lights as the shaders read them (`light_at` of `shaders/lighting.wgsl`): per light
    /// a vector — directional: the unit vector from the surface towards the light, w = 0; point:
    /// its position in metres, w = 1 — and its radiance: colour × intensity (rgb), a point light's
    /// range in metres (a; 0 = unbounded).
    pub fn lights(&self) -> impl ExactSizeIterator<Item = ([f32; 4], [f32; 4])> + '_ {
        let count = (self.light_count[0] as usize).min(self.lights.len());
        self.lights[..count].iter().map(|l| (l.vector, l.radiance))
    }

    /// The hemisphere ambient: linear RGB from above (+Y) and from below.
    pub fn ambient(&self) -> ([f32; 3], [f32; 3]) {
        let rgb = |c: [f32; 4]| [c[0], c[1], c[2]];
        (rgb(self.ambient_sky), rgb(self.ambient_ground))
    }
}

/// The skinning pass's counts (`SkinningUniforms` in `skinning.wgsl`; binding 0), written once.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SkinningUniforms {
    /// Welded skin vertices.
    pub vertex_count: u32,
    /// Influence slots per vertex: 4 or 8 (`SkinWeights::influences_per_vertex`); 0 without
    /// skin weights.
    pub influences_per_vertex: u32,
    /// Morph targets; 0 without them.
    pub target_count: u32,
    /// Padding to 16 bytes.
    pub pad0: u32,
}

/// One welded skin vertex (`SkinnedVertex` in `skinning.wgsl` and `fur_common.wgsl`): the bind
/// pose the skinning pass reads and the posed vertex it writes, which the skin, shell and fin
/// shaders read by welded vertex index.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SkinnedVertex {
    /// Position in metres (xyz; w = 1).
    pub position: [f32; 4],
    /// Unit normal (xyz; w = 0).
    pub normal: [f32; 4],
}

/// One input vertex of the shell readback probe (`ProbeVertex` in `shell.wgsl`, read by
/// `cs_shell_positions`; [`crate::FurRenderer::shell_positions`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ProbeVertex {
    /// Bind-pose position in metres (xyz; w unused).
    pub position: [f32; 4],
    /// Bind-pose unit normal (xyz; w unused).
    pub normal: [f32; 4],
    /// Welded vertex index (where an animated pack's posed root is read).
    pub vertex_index: u32,
    /// Padding to the struct's 16-byte alignment.
    pub pad: [u32; 3],
}

/// Vertex attributes of [`SurfaceVertex`], locations 0–6 as in `skin.wgsl` / `shell.wgsl`.
pub const SURFACE_ATTRIBUTES: [wgpu::VertexAttribute; 7] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32x4, 3 => Float32x2, 4 => Uint32, 5 => Uint32, 6 => Uint32
];

/// Vertex attributes of [`FinVertex`], locations 0–8 as in `fin.wgsl`.
pub const FIN_ATTRIBUTES: [wgpu::VertexAttribute; 9] = wgpu::vertex_attr_array![
    0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x4, 4 => Float32, 5 => Float32, 6 => Uint32,
    7 => Uint32, 8 => Uint32x3
];

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn validated(name: &str, source: &str) -> (naga::Module, naga::valid::ModuleInfo) {
        let module =
            naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
        let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
        (module, info)
    }

    /// The probe vertex of `cs_shell_positions` (two `vec4<f32>`, the welded index, padding).
    #[test]
    fn the_shell_probe_vertex_matches_the_shader() {
        use std::mem::{offset_of, size_of};
        let (module, _) = validated("shell.wgsl", SHELL_WGSL);
        let (span, members) = wgsl_struct(&module, "ProbeVertex").expect("shell.wgsl declares ProbeVertex");
        assert_eq!(span as usize, size_of::<ProbeVertex>());
        let pad = offset_of!(ProbeVertex, pad);
        let rust = [
            ("position", offset_of!(ProbeVertex, position)),
            ("normal", offset_of!(ProbeVertex, normal)),
            ("vertex_index", offset_of!(ProbeVertex, vertex_index)),
            ("pad0", pad),
            ("pad1", pad + 4),
            ("pad2", pad + 8),
        ];
        let got: Vec<(&str, usize)> = members.iter().map(|(n, o)| (n.as_str(), *o as usize)).collect();
        assert_eq!(got, rust);
    }

    const SHADERS: [(&str, &str); 9] = [
        ("depth_pyramid.wgsl", DEPTH_PYRAMID_WGSL),
        ("fur_physics.wgsl", FUR_PHYSICS_WGSL),
        ("skin.wgsl", SKIN_WGSL),
        ("shell.wgsl", SHELL_WGSL),
        ("fin.wgsl", FIN_WGSL),
        ("skinning.wgsl", SKINNING_WGSL),
        ("silhouette.wgsl", SILHOUETTE_WGSL),
        ("blades.wgsl", BLADES_WGSL),
        ("blade_cull.wgsl", BLADE_CULL_WGSL),
    ];

    #[test]
    fn every_shader_parses_and_validates() {
        let mut entry_points = Vec::new();
        for (name, source) in SHADERS {
            let (module, _) = validated(name, source);
            entry_points.extend(module.entry_points.iter().map(|e| (e.name.clone(), e.workgroup_size)));
        }
        entry_points.sort();
        let names: Vec<&str> = entry_points.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            [
                "cs_blades",
                "cs_compact",
                "cs_cull_blades",
                "cs_cull_clusters",
                "cs_depth_copy",
                "cs_depth_reduce",
                "cs_energy",
                "cs_guard",
                "cs_pose_all",
                "cs_pose_anchored",
                "cs_pose_between",
                "cs_pose_blend",
                "cs_pose_free",
                "cs_pose_rest",
                "cs_pose_tips",
                "cs_scale",
                "cs_scan_blocks",
                "cs_shell_positions",
                "cs_silhouette",
                "cs_skin",
                "cs_step",
                "cs_teleport",
                "cs_xpbd_step",
                "fs_blade",
                "fs_fin",
                "fs_shell",
                "fs_skin",
                "vs_blade",
                "vs_fin",
                "vs_shell",
                "vs_silhouette_fin",
                "vs_skin"
            ]
        );
        // The dispatch sizes the Rust side computes from.
        let size = |name: &str| entry_points.iter().find(|(n, _)| n == name).map(|(_, s)| s[0]);
        assert_eq!(size("cs_blades"), Some(64));
        assert_eq!(size("cs_cull_clusters"), Some(64));
        // The culling passes' widths: culling.rs's tests (the_culling_workgroups_are_one_block).
    }

    /// The workgroup width of entry point `name` in the first shader that has it.
    pub(crate) fn workgroup_width(name: &str) -> Option<u32> {
        SHADERS.iter().find_map(|(file, source)| {
            let (module, _) = validated(file, source);
            module.entry_points.iter().find(|e| e.name == name).map(|e| e.workgroup_size[0])
        })
    }

    /// (size, member names and offsets) of the WGSL struct `name`, from naga's layout.
    fn wgsl_struct(module: &naga::Module, name: &str) -> Option<(u32, Vec<(String, u32)>)> {
        module.types.iter().find_map(|(_, ty)| match (&ty.name, &ty.inner) {
            (Some(n), naga::TypeInner::Struct { members, span }) if n == name => {
                Some((*span, members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect()))
            }
            _ => None,
        })
    }

    /// Checks the WGSL struct `name` against its Rust mirror (`size` bytes, `rust` members and
    /// offsets) in every shader that declares it; returns how many do.
    pub(crate) fn check_layout(name: &str, size: usize, rust: &[(&str, usize)]) -> usize {
        let mut checked = 0;
        for (file, source) in SHADERS {
            let (module, _) = validated(file, source);
            let Some((span, members)) = wgsl_struct(&module, name) else { continue };
            // naga's layouter agrees with the span recorded in the struct type.
            let mut layouter = naga::proc::Layouter::default();
            layouter.update(module.to_ctx()).expect("a validated module lays out");
            let handle = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).map(|(h, _)| h).unwrap();
            assert_eq!(layouter[handle].size, span, "{file}: {name}");
            assert_eq!(span as usize, size, "{file}: size of {name}");
            let got: Vec<(&str, usize)> = members.iter().map(|(n, o)| (n.as_str(), *o as usize)).collect();
            assert_eq!(got, rust, "{file}: members of {name}");
            checked += 1;
        }
        checked
    }

    #[test]
    fn uniform_structs_match_the_shaders() {
        use std::mem::{offset_of, size_of};
        let frame = [
            ("view_proj", offset_of!(FrameUniforms, view_proj)),
            ("camera_pos", offset_of!(FrameUniforms, camera_pos)),
            ("ambient_sky", offset_of!(FrameUniforms, ambient_sky)),
            ("ambient_ground", offset_of!(FrameUniforms, ambient_ground)),
            ("light_count", offset_of!(FrameUniforms, light_count)),
            ("lights", offset_of!(FrameUniforms, lights)),
            ("model", offset_of!(FrameUniforms, model)),
            ("viewport", offset_of!(FrameUniforms, viewport)),
            ("shells", offset_of!(FrameUniforms, shells)),
        ];
        assert_eq!(check_layout("Frame", size_of::<FrameUniforms>(), &frame), 4, "Frame: the fur shaders, blades.wgsl");
        let fur = [
            ("tint", offset_of!(FurUniforms, tint)),
            ("fur_length_m", offset_of!(FurUniforms, fur_length_m)),
            ("shear_exponent", offset_of!(FurUniforms, shear_exponent)),
            ("alpha_threshold", offset_of!(FurUniforms, alpha_threshold)),
            ("atlas_layers", offset_of!(FurUniforms, atlas_layers)),
            ("drawn_layers", offset_of!(FurUniforms, drawn_layers)),
            ("fin_repeat_m", offset_of!(FurUniforms, fin_repeat_m)),
            ("scale_layout", offset_of!(FurUniforms, scale_layout)),
            ("pad1", offset_of!(FurUniforms, pad1)),
            ("tip_color", offset_of!(FurUniforms, tip_color)),
            ("secondary_tint", offset_of!(FurUniforms, secondary_tint)),
            ("specular", offset_of!(FurUniforms, specular)),
            ("strand", offset_of!(FurUniforms, strand)),
            ("stacking", offset_of!(FurUniforms, stacking)),
        ];
        assert_eq!(check_layout("Fur", size_of::<FurUniforms>(), &fur), 3, "Fur is in all three shaders");
        let params = [
            ("vertex_count", offset_of!(SkinningUniforms, vertex_count)),
            ("influences_per_vertex", offset_of!(SkinningUniforms, influences_per_vertex)),
            ("target_count", offset_of!(SkinningUniforms, target_count)),
            ("pad0", offset_of!(SkinningUniforms, pad0)),
        ];
        assert_eq!(check_layout("SkinningUniforms", size_of::<SkinningUniforms>(), &params), 1, "in skinning.wgsl");
        // The grass structs (BladeUniforms, CullUniforms): blades.rs's and culling.rs's tests.
    }

    #[test]
    fn storage_structs_match_the_shaders() {
        use std::mem::{offset_of, size_of};
        let skinned =
            [("position", offset_of!(SkinnedVertex, position)), ("normal", offset_of!(SkinnedVertex, normal))];
        // Written by skinning.wgsl, read by the three fur shaders (fur_common.wgsl) and the
        // silhouette selection.
        assert_eq!(check_layout("SkinnedVertex", size_of::<SkinnedVertex>(), &skinned), 5);
        // The silhouette and grass storage structs: silhouette.rs's and blades.rs's tests.
    }

    #[test]
    fn vertex_attributes_cover_the_vertex_structs() {
        use std::mem::{offset_of, size_of};
        // Attribute offsets are the struct's field offsets, and the last attribute ends at the
        // struct's end (no hidden padding that the stride would have to skip).
        let surface = [
            offset_of!(SurfaceVertex, position),
            offset_of!(SurfaceVertex, normal),
            offset_of!(SurfaceVertex, color),
            offset_of!(SurfaceVertex, uv),
            offset_of!(SurfaceVertex, vertex_index),
            offset_of!(SurfaceVertex, flags),
            offset_of!(SurfaceVertex, corner_index),
        ];
        let got: Vec<usize> = SURFACE_ATTRIBUTES.iter().map(|a| a.offset as usize).collect();
        assert_eq!(got, surface);
        assert_eq!(SURFACE_ATTRIBUTES[6].offset as usize + 4, size_of::<SurfaceVertex>());
        let fin = [
            offset_of!(FinVertex, position),
            offset_of!(FinVertex, normal),
            offset_of!(FinVertex, face_normal),
            offset_of!(FinVertex, color),
            offset_of!(FinVertex, along_m),
            offset_of!(FinVertex, height),
            offset_of!(FinVertex, vertex_index),
            offset_of!(FinVertex, corner_index),
            offset_of!(FinVertex, face_vertices),
        ];
        let got: Vec<usize> = FIN_ATTRIBUTES.iter().map(|a| a.offset as usize).collect();
        assert_eq!(got, fin);
        assert_eq!(FIN_ATTRIBUTES[8].offset as usize + 12, size_of::<FinVertex>());
    }
}
