//! The renderer's shaders for engines that draw with their own graphics API: every entry point
//! of the WGSL the renderer runs, translated by naga into SPIR-V, GLSL 4.50, HLSL (shader model
//! 5.1) or MSL (2.0) once per combination of the `override` switches it reads (resolved: the
//! output has none), with a manifest of what each file binds, reads and expects
//! (docs/c-api.md "Shaders").
//!
//! An override is part of an entry point's variants when changing it changes the translated
//! code (switches the entry point never reads do not multiply its files). Combinations the
//! renderer never builds are left out: `ALPHA_TO_COVERAGE` only with `ALPHA_BLEND` off, as in
//! `pipelines.rs`. Output is deterministic: the same build gives byte-identical files.

use std::collections::BTreeMap;

use naga::back::{glsl, hlsl, msl, spv};
use naga::valid::{Capabilities, ModuleInfo, ValidationFlags, Validator};
use naga::{AddressSpace, ShaderStage, StorageAccess, TypeInner};
use serde_json::{Value, json};

use crate::RenderError;
use crate::shaders::{
    BLADE_CULL_WGSL, BLADES_WGSL, DEPTH_PYRAMID_WGSL, FIN_WGSL, FUR_PHYSICS_WGSL, SHELL_WGSL, SILHOUETTE_WGSL,
    SKIN_WGSL, SKINNING_WGSL,
};

/// HLSL space and `b` register of the constant buffer naga adds for what HLSL has no built-in
/// for (`_NagaConstants`: `int first_vertex, first_instance; uint other` — a draw's first vertex
/// and first instance, or a dispatch's workgroup counts x, y, z), outside the groups furbake's
/// modules use (0 and 1).
const HLSL_SPECIAL_CONSTANTS: (u8, u32) = (8, 0);

/// A shading language the shaders are exported to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShaderTarget {
    /// SPIR-V 1.0 binaries for Vulkan (`.spv`; descriptor set = WGSL group, binding = binding;
    /// clip space as Vulkan's, y down).
    Spirv,
    /// GLSL 4.50 core for OpenGL 4.5 (`.vert`, `.frag`, `.comp`; explicit bindings per resource
    /// kind in the manifest; clip space as WGSL's, so the host sets
    /// `glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE)`).
    Glsl,
    /// HLSL for shader model 5.1 (`.hlsl`; register = binding, space = group).
    Hlsl,
    /// Metal Shading Language 2.0 (`.metal`; buffer, texture and sampler slots in the manifest).
    Msl,
}

impl ShaderTarget {
    /// Every target.
    pub const ALL: [ShaderTarget; 4] = [ShaderTarget::Spirv, ShaderTarget::Glsl, ShaderTarget::Hlsl, ShaderTarget::Msl];

    /// `spirv`, `glsl`, `hlsl` or `msl`.
    pub fn name(self) -> &'static str {
        match self {
            ShaderTarget::Spirv => "spirv",
            ShaderTarget::Glsl => "glsl",
            ShaderTarget::Hlsl => "hlsl",
            ShaderTarget::Msl => "msl",
        }
    }

    /// Parses [`ShaderTarget::name`].
    pub fn from_name(name: &str) -> Option<ShaderTarget> {
        ShaderTarget::ALL.into_iter().find(|t| t.name() == name)
    }

    fn extension(self, stage: ShaderStage) -> &'static str {
        match (self, stage) {
            (ShaderTarget::Spirv, _) => "spv",
            (ShaderTarget::Glsl, ShaderStage::Vertex) => "vert",
            (ShaderTarget::Glsl, ShaderStage::Fragment) => "frag",
            (ShaderTarget::Glsl, _) => "comp",
            (ShaderTarget::Hlsl, _) => "hlsl",
            (ShaderTarget::Msl, _) => "metal",
        }
    }
}

/// One exported file: its name (no directory) and bytes.
#[derive(Clone, Debug)]
pub struct ExportedShader {
    /// File name, `MODULE.ENTRY_POINT[.VARIANT].EXT`.
    pub file: String,
    /// The translated shader.
    pub bytes: Vec<u8>,
}

/// What [`export_shaders`] makes: the files, and the manifest (`manifest.json`) that describes
/// them.
#[derive(Clone, Debug)]
pub struct ShaderExport {
    /// The translated shaders, in module, entry point and variant order.
    pub files: Vec<ExportedShader>,
    /// The manifest: per file its module, entry point, stage, resolved switches, bindings
    /// (with the target's binding numbers and what the C interface gives for each), vertex
    /// inputs and workgroup size; the layouts of the uniform and storage structs.
    pub manifest: Value,
}

/// The renderer's shader modules: name, WGSL.
const MODULES: [(&str, &str); 9] = [
    ("skin", SKIN_WGSL),
    ("shell", SHELL_WGSL),
    ("fin", FIN_WGSL),
    ("skinning", SKINNING_WGSL),
    ("silhouette", SILHOUETTE_WGSL),
    ("blades", BLADES_WGSL),
    ("blade_cull", BLADE_CULL_WGSL),
    ("fur_physics", FUR_PHYSICS_WGSL),
    ("depth_pyramid", DEPTH_PYRAMID_WGSL),
];

/// What feeds each binding, by variable name: the C interface's view, or how the renderer
/// fills it (docs/design.md has the layouts).
fn source_of(module: &str, variable: &str) -> &'static str {
    match (module, variable) {
        (_, "frame") => "host: camera, lights and model matrix (FrameUniforms layout, struct Frame)",
        (_, "fur") => {
            "host: fur uniforms (struct Fur) from furbake_pack_shell_atlas (fur_length_m, layers) and the pack's shading settings"
        }
        (_, "scale_vectors") => "furbake_world_fur_frame().scale_vectors, one vec4 per scale vector (xyz; w = 0)",
        (_, "shadow") => "furbake_pack_shell_atlas().shadow",
        (_, "shell_alpha") => "furbake_pack_shell_atlas().alpha as an R8 2D array texture with mipmaps",
        (_, "fin_alpha") => "furbake_pack_fin_atlas().alpha as an R8 2D texture with mipmaps",
        (_, "repeat_sampler") => {
            "host: a trilinear sampler repeating in u and v, anisotropic up to the look's anisotropy (FurbakeFurLook, Fur.stacking.y: 16 by default; 1 for the alpha test)"
        }
        (_, "fin_sampler") => {
            "host: a trilinear sampler repeating in u, clamped in v, anisotropic up to the look's anisotropy (as repeat_sampler)"
        }
        (_, "skinned" | "sil_vertices" | "vertices") => {
            "the skinning pass's output (skinning.cs_skin skinned_out), or the bind pose of furbake_pack_skin_mesh for a static pack"
        }
        (_, "stacking") => {
            "host: per-asset stacking exponents (the renderer's stacking table; 1.0 everywhere draws plain alpha)"
        }
        ("skinning", "bind_vertices") => "furbake_pack_skin_mesh positions and normals (struct SkinnedVertex)",
        ("skinning", "influence_binds") => "furbake_pack_skin_weights().binds, two u16 per word",
        ("skinning", "influence_weights") => "furbake_pack_skin_weights().weights",
        ("skinning", "skinning_matrices") => "furbake_world_skin_pose().skinning_matrices",
        ("skinning", "morph_weights") => "furbake_world_skin_pose().morph_weights",
        ("skinning", "morph_deltas") => {
            "furbake_pack_morph_targets position deltas, then normal deltas (with MORPH_NORMALS)"
        }
        ("skinning", "params") => "host: vertex, influence and morph counts (struct SkinningUniforms)",
        ("skinning", "skinned_out") => "output: this frame's posed welded vertices",
        (_, "edges" | "sil_edges") => {
            "furbake_pack_skin_mesh interior edges with their two triangles (struct SilhouetteEdge)"
        }
        (_, "instances" | "sil_instances" | "args") => "output of the selection or culling pass of this frame",
        (_, "sil_colors") => "furbake_pack_skin_mesh().colors",
        (_, "blades") => "furbake_pack_blade_field positions, yaw, height scale and cluster (struct Blade)",
        (_, "corner_forces") => "furbake_world_grass_frame().corner_forces",
        (_, "payload" | "vertex_map" | "reference") => {
            "furbake_pack_keyframe_table (displacements, vertex_map, reference_positions)"
        }
        (_, "params" | "cull") => "host: grass uniforms of this frame (struct BladeUniforms / CullUniforms)",
        (_, "cluster_bounds") => "host: per-cluster bounds from furbake_pack_blade_field",
        (_, "delayed" | "delayed_directions") => "host: delayed-attenuation wind sources (empty without them)",
        (_, "decisions" | "work") => "scratch of the culling passes",
        (_, "positions_out" | "probe_out" | "probe_tangents" | "probe_vertices") => "readback of the renderer's tests",
        _ => "see docs/design.md",
    }
}

/// The values an override takes: both for a switch; 1 to 4 lights for `LIGHT_SLOTS`.
fn override_values(name: &str, ty: &TypeInner) -> Vec<f64> {
    match (name, ty) {
        (_, TypeInner::Scalar(s)) if s.kind == naga::ScalarKind::Bool => vec![0.0, 1.0],
        (LIGHT_SLOTS, _) => (1..=furbake_runtime::MAX_LIGHTS as u32).map(f64::from).collect(),
        _ => Vec::new(),
    }
}

/// The one override that is a count, not a switch (named by its value in file names).
const LIGHT_SLOTS: &str = "LIGHT_SLOTS";

fn export_error(entry: &str, what: impl std::fmt::Display) -> RenderError {
    RenderError::Parameter { what: format!("shader export of {entry}: {what}") }
}

/// Translates every entry point of every shader module into `target`, once per variant, with
/// its manifest.
pub fn export_shaders(target: ShaderTarget) -> Result<ShaderExport, RenderError> {
    let mut files = Vec::new();
    let mut entries = Vec::new();
    let mut structs = BTreeMap::new();
    for (name, source) in MODULES {
        let module = naga::front::wgsl::parse_str(source).map_err(|e| export_error(name, e.emit_to_string(source)))?;
        let info = Validator::new(ValidationFlags::all(), Capabilities::all())
            .validate(&module)
            .map_err(|e| export_error(name, e.emit_to_string(source)))?;
        describe_structs(&module, &mut structs);
        let glsl = glsl_bindings(&module);
        for ep in &module.entry_points {
            let label = format!("{name}.{}", ep.name);
            let switches = used_overrides(target, &module, &info, &glsl, ep, &label)?;
            for constants in combinations(&switches) {
                let bytes = translate(target, &module, &info, &glsl, ep.stage, &ep.name, &constants)
                    .map_err(|e| export_error(&label, e))?;
                let variant = variant_name(&constants);
                let file = match variant.is_empty() {
                    true => format!("{label}.{}", target.extension(ep.stage)),
                    false => format!("{label}.{variant}.{}", target.extension(ep.stage)),
                };
                entries.push(json!({
                    "file": file,
                    "module": name,
                    "entry_point": ep.name,
                    "stage": stage_name(ep.stage),
                    "constants": constants.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
                    "workgroup_size": (ep.stage == ShaderStage::Compute).then_some(ep.workgroup_size),
                    "bindings": bindings(target, name, &module, &info, &glsl, ep),
                    "vertex_inputs": vertex_inputs(&module, ep),
                }));
                let text = String::from_utf8_lossy(&bytes);
                if target == ShaderTarget::Glsl {
                    // Uniforms naga adds that the host sets per draw (GLSL's instance index does
                    // not include the first instance).
                    let extra: Vec<&str> =
                        ["naga_vs_first_instance"].into_iter().filter(|u| text.contains(u)).collect();
                    if let Some(last) = entries.last_mut() {
                        last["host_uniforms"] = json!(extra);
                    }
                }
                if target == ShaderTarget::Hlsl && text.contains("_NagaConstants.") {
                    // The constant buffer naga reads where HLSL lacks a built-in (SV_InstanceID
                    // leaves out the draw's first instance, and there is no workgroup count).
                    if let Some(last) = entries.last_mut() {
                        last["host_constants"] = json!({
                            "name": "_NagaConstants",
                            "space": HLSL_SPECIAL_CONSTANTS.0,
                            "register": HLSL_SPECIAL_CONSTANTS.1,
                        });
                    }
                }
                files.push(ExportedShader { file, bytes });
            }
        }
    }
    let manifest = json!({
        "format": "furbake-shaders/1",
        "target": target.name(),
        "language": match target {
            ShaderTarget::Spirv => "SPIR-V 1.0 (Vulkan clip space)",
            ShaderTarget::Glsl => "GLSL 4.50 core (WGSL clip space: glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE))",
            ShaderTarget::Hlsl => "HLSL shader model 5.1",
            ShaderTarget::Msl => "Metal Shading Language 2.0",
        },
        "furbake_version": env!("CARGO_PKG_VERSION"),
        "files": entries,
        "structs": structs,
    });
    Ok(ShaderExport { files, manifest })
}

fn stage_name(stage: ShaderStage) -> &'static str {
    match stage {
        ShaderStage::Vertex => "vertex",
        ShaderStage::Fragment => "fragment",
        _ => "compute",
    }
}

/// The overrides whose value changes `ep`'s translated code, with the values each takes.
fn used_overrides(
    target: ShaderTarget,
    module: &naga::Module,
    info: &ModuleInfo,
    glsl: &GlslBindings,
    ep: &naga::EntryPoint,
    label: &str,
) -> Result<Vec<(String, Vec<f64>)>, RenderError> {
    let mut used = Vec::new();
    for (_, o) in module.overrides.iter() {
        let Some(name) = o.name.clone() else { continue };
        let values = override_values(&name, &module.types[o.ty].inner);
        if values.len() < 2 {
            continue;
        }
        let mut outputs = Vec::new();
        for v in &values[..2] {
            let constants = BTreeMap::from([(name.clone(), *v)]);
            outputs.push(
                translate(target, module, info, glsl, ep.stage, &ep.name, &constants)
                    .map_err(|e| export_error(label, e))?,
            );
        }
        if outputs[0] != outputs[1] {
            used.push((name, values));
        }
    }
    Ok(used)
}

/// Every combination of the switches' values the renderer can build, in a fixed order.
fn combinations(switches: &[(String, Vec<f64>)]) -> Vec<BTreeMap<String, f64>> {
    let mut all = vec![BTreeMap::new()];
    for (name, values) in switches {
        all = all
            .into_iter()
            .flat_map(|c| {
                values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.insert(name.clone(), *v);
                    c
                })
            })
            .collect();
    }
    // Alpha to coverage is built only for alpha-tested (not blended) shells and fins.
    all.retain(|c| !(c.get("ALPHA_TO_COVERAGE") == Some(&1.0) && c.get("ALPHA_BLEND") == Some(&1.0)));
    all
}

/// `lambert-shadow-strand.light_slots2`-style name: the switches on, then numeric values.
fn variant_name(constants: &BTreeMap<String, f64>) -> String {
    let (counts, switches): (Vec<_>, Vec<_>) = constants.iter().partition(|(k, _)| k.as_str() == LIGHT_SLOTS);
    let on: Vec<String> = switches.iter().filter(|(_, v)| **v == 1.0).map(|(k, _)| k.to_lowercase()).collect();
    let mut parts = Vec::new();
    if !on.is_empty() {
        parts.push(on.join("-"));
    } else if !switches.is_empty() && counts.is_empty() {
        parts.push("none".to_string());
    }
    parts.extend(counts.iter().map(|(k, v)| format!("{}{v}", k.to_lowercase())));
    parts.join(".")
}

/// The module with `constants` resolved, translated for one entry point.
fn translate(
    target: ShaderTarget,
    module: &naga::Module,
    info: &ModuleInfo,
    glsl: &GlslBindings,
    stage: ShaderStage,
    entry: &str,
    constants: &BTreeMap<String, f64>,
) -> Result<Vec<u8>, String> {
    let pipeline_constants: naga::back::PipelineConstants = constants.iter().map(|(k, v)| (k.clone(), *v)).collect();
    let (module, info) =
        naga::back::pipeline_constants::process_overrides(module, info, Some((stage, entry)), &pipeline_constants)
            .map_err(|e| e.to_string())?;
    let ep = module.entry_points.iter().find(|e| e.name == entry && e.stage == stage).ok_or("no such entry point")?;
    match target {
        ShaderTarget::Spirv => {
            let options = spv::Options {
                // Fixed flags (the default adds debug names in debug builds: the output would
                // depend on the build).
                flags: spv::WriterFlags::ADJUST_COORDINATE_SPACE
                    | spv::WriterFlags::LABEL_VARYINGS
                    | spv::WriterFlags::CLAMP_FRAG_DEPTH,
                ..spv::Options::default()
            };
            let pipeline = spv::PipelineOptions { shader_stage: stage, entry_point: entry.into() };
            let words = spv::write_vec(&module, &info, &options, Some(&pipeline)).map_err(|e| e.to_string())?;
            Ok(words.iter().flat_map(|w| w.to_le_bytes()).collect())
        }
        ShaderTarget::Glsl => {
            let binding_map = glsl.iter().map(|(binding, (_, slot))| (*binding, *slot as u8)).collect();
            let options = glsl::Options {
                version: glsl::Version::Desktop(450),
                writer_flags: glsl::WriterFlags::empty(),
                binding_map,
                zero_initialize_workgroup_memory: true,
            };
            let pipeline = glsl::PipelineOptions { shader_stage: stage, entry_point: entry.into(), multiview: None };
            let mut out = String::new();
            glsl::Writer::new(
                &mut out,
                &module,
                &info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .and_then(|mut w| w.write())
            .map_err(|e| e.to_string())?;
            Ok(out.into_bytes())
        }
        ShaderTarget::Hlsl => {
            let options = hlsl::Options {
                fake_missing_bindings: true,
                special_constants_binding: Some(hlsl::BindTarget {
                    space: HLSL_SPECIAL_CONSTANTS.0,
                    register: HLSL_SPECIAL_CONSTANTS.1,
                    ..Default::default()
                }),
                ..hlsl::Options::default()
            };
            let pipeline = hlsl::PipelineOptions { entry_point: Some((stage, entry.into())) };
            let mut out = String::new();
            hlsl::Writer::new(&mut out, &options, &pipeline).write(&module, &info, None).map_err(|e| e.to_string())?;
            Ok(out.into_bytes())
        }
        ShaderTarget::Msl => {
            let (resources, sizes) = msl_bindings(&module, &info, ep);
            let map = msl::EntryPointResources { resources, immediates_buffer: None, sizes_buffer: Some(sizes) };
            let options = msl::Options {
                lang_version: (2, 0),
                per_entry_point_map: BTreeMap::from([(entry.to_string(), map)]),
                fake_missing_bindings: false,
                ..msl::Options::default()
            };
            let pipeline =
                msl::PipelineOptions { entry_point: Some((stage, entry.into())), ..msl::PipelineOptions::default() };
            let (out, _) = msl::write_string(&module, &info, &options, &pipeline).map_err(|e| e.to_string())?;
            Ok(out.into_bytes())
        }
    }
}

/// The kind of a resource binding, in the words the manifest uses.
fn resource_kind(module: &naga::Module, var: &naga::GlobalVariable) -> &'static str {
    match (var.space, &module.types[var.ty].inner) {
        (AddressSpace::Uniform, _) => "uniform_buffer",
        (AddressSpace::Storage { access }, _) if access.contains(StorageAccess::STORE) => "storage_buffer_read_write",
        (AddressSpace::Storage { .. }, _) => "storage_buffer_read",
        (_, TypeInner::Sampler { .. }) => "sampler",
        (_, TypeInner::Image { .. }) => "texture",
        _ => "other",
    }
}

/// The global resources `ep` uses, in (group, binding) order.
fn used_resources<'a>(
    module: &'a naga::Module,
    info: &ModuleInfo,
    ep: &naga::EntryPoint,
) -> Vec<(naga::ResourceBinding, &'a naga::GlobalVariable)> {
    let index = module.entry_points.iter().position(|e| e.name == ep.name && e.stage == ep.stage).unwrap_or(0);
    let ep_info = info.get_entry_point(index);
    let mut used: Vec<_> = module
        .global_variables
        .iter()
        .filter(|(h, _)| !ep_info[*h].is_empty())
        .filter_map(|(_, v)| v.binding.map(|b| (b, v)))
        .collect();
    used.sort_by_key(|(b, _)| (b.group, b.binding));
    used
}

/// Each resource's OpenGL binding namespace and number.
type GlslBindings = BTreeMap<naga::ResourceBinding, (&'static str, u32)>;

/// GLSL binding numbers: one counter per OpenGL binding namespace (uniform blocks, shader
/// storage blocks, texture units), over every resource of the module in (group, binding) order,
/// numbered before the overrides are resolved for one entry point (which drops the resources it
/// does not use), so the stages of one program agree (OpenGL binding points are shared by the
/// linked stages).
fn glsl_bindings(module: &naga::Module) -> GlslBindings {
    let mut resources: Vec<_> = module.global_variables.iter().filter_map(|(_, v)| v.binding.map(|b| (b, v))).collect();
    resources.sort_by_key(|(b, _)| (b.group, b.binding));
    let mut next = BTreeMap::new();
    let mut map = BTreeMap::new();
    for (binding, var) in resources {
        let space = match resource_kind(module, var) {
            "uniform_buffer" => "uniform_block",
            "storage_buffer_read" | "storage_buffer_read_write" => "shader_storage_block",
            // A sampler merges with its texture into one GLSL sampler on the texture's unit.
            "sampler" => continue,
            _ => "texture_unit",
        };
        let slot = next.entry(space).or_insert(0u32);
        map.insert(binding, (space, *slot));
        *slot += 1;
    }
    map
}

/// MSL slots: one counter per kind (buffers, textures, samplers) in (group, binding) order; the
/// buffer of runtime-array sizes takes the next buffer slot.
fn msl_bindings(module: &naga::Module, info: &ModuleInfo, ep: &naga::EntryPoint) -> (msl::BindingMap, u8) {
    let (mut buffers, mut textures, mut samplers) = (0u8, 0u8, 0u8);
    let mut map = msl::BindingMap::new();
    for (binding, var) in used_resources(module, info, ep) {
        let mut target = msl::BindTarget::default();
        match resource_kind(module, var) {
            "texture" => {
                target.texture = Some(textures);
                textures += 1;
            }
            "sampler" => {
                target.sampler = Some(msl::BindSamplerTarget::Resource(samplers));
                samplers += 1;
            }
            kind => {
                target.buffer = Some(buffers);
                target.mutable = kind == "storage_buffer_read_write";
                buffers += 1;
            }
        }
        map.insert(binding, target);
    }
    (map, buffers)
}

fn bindings(
    target: ShaderTarget,
    module_name: &str,
    module: &naga::Module,
    info: &ModuleInfo,
    glsl: &GlslBindings,
    ep: &naga::EntryPoint,
) -> Vec<Value> {
    let msl = (target == ShaderTarget::Msl).then(|| msl_bindings(module, info, ep).0);
    used_resources(module, info, ep)
        .into_iter()
        .map(|(b, var)| {
            let name = var.name.clone().unwrap_or_default();
            let ty = &module.types[var.ty];
            let mut entry = json!({
                "group": b.group,
                "binding": b.binding,
                "name": name,
                "kind": resource_kind(module, var),
                "type": type_name(module, var.ty),
                "source": source_of(module_name, &name),
            });
            match ty.inner {
                TypeInner::Struct { span, .. } => entry["size"] = json!(span),
                TypeInner::Array { stride, .. } => entry["stride"] = json!(stride),
                _ => {}
            }
            match target {
                ShaderTarget::Glsl => {
                    entry["glsl_binding"] = glsl.get(&b).map_or(Value::Null, |(space, slot)| json!({ "namespace": space, "binding": slot }));
                }
                ShaderTarget::Hlsl => entry["hlsl_register"] = json!({ "register": b.binding, "space": b.group }),
                ShaderTarget::Msl => {
                    let t = msl.as_ref().and_then(|m| m.get(&b));
                    entry["msl_slot"] = json!({
                        "buffer": t.and_then(|t| t.buffer),
                        "texture": t.and_then(|t| t.texture),
                        "sampler": t.and_then(|t| match t.sampler { Some(msl::BindSamplerTarget::Resource(s)) => Some(s), _ => None }),
                    });
                }
                ShaderTarget::Spirv => entry["spirv"] = json!({ "descriptor_set": b.group, "binding": b.binding }),
            }
            entry
        })
        .collect()
}

/// The entry point's vertex inputs: location, name and WGSL type.
fn vertex_inputs(module: &naga::Module, ep: &naga::EntryPoint) -> Vec<Value> {
    if ep.stage != ShaderStage::Vertex {
        return Vec::new();
    }
    let mut inputs = Vec::new();
    for arg in &ep.function.arguments {
        let mut push = |name: Option<&String>, binding: Option<&naga::Binding>, ty: naga::Handle<naga::Type>| {
            if let Some(naga::Binding::Location { location, .. }) = binding {
                inputs.push(json!({ "location": location, "name": name, "type": type_name(module, ty) }));
            } else if let Some(naga::Binding::BuiltIn(b)) = binding {
                inputs.push(json!({ "builtin": format!("{b:?}").to_lowercase(), "name": name }));
            }
        };
        match &module.types[arg.ty].inner {
            TypeInner::Struct { members, .. } if arg.binding.is_none() => {
                for m in members {
                    push(m.name.as_ref(), m.binding.as_ref(), m.ty);
                }
            }
            _ => push(arg.name.as_ref(), arg.binding.as_ref(), arg.ty),
        }
    }
    inputs
}

/// A type's WGSL-like name (`vec4<f32>`, `array<Blade>`, `Frame`).
fn type_name(module: &naga::Module, ty: naga::Handle<naga::Type>) -> String {
    let t = &module.types[ty];
    if let Some(name) = &t.name {
        return name.clone();
    }
    match &t.inner {
        TypeInner::Array { base, size, .. } => match size {
            naga::ArraySize::Constant(n) => format!("array<{}, {n}>", type_name(module, *base)),
            _ => format!("array<{}>", type_name(module, *base)),
        },
        TypeInner::Scalar(scalar) => scalar_name(*scalar),
        TypeInner::Atomic(scalar) => format!("atomic<{}>", scalar_name(*scalar)),
        TypeInner::Vector { size, scalar } => format!("vec{}<{}>", *size as u8, scalar_name(*scalar)),
        TypeInner::Matrix { columns, rows, scalar } => {
            format!("mat{}x{}<{}>", *columns as u8, *rows as u8, scalar_name(*scalar))
        }
        TypeInner::Image { dim, arrayed, .. } => {
            format!("texture_{dim:?}{}", if *arrayed { "_array" } else { "" }).to_lowercase()
        }
        TypeInner::Sampler { .. } => "sampler".into(),
        other => format!("{other:?}"),
    }
}

fn scalar_name(s: naga::Scalar) -> String {
    match s.kind {
        naga::ScalarKind::Bool => "bool".into(),
        naga::ScalarKind::Float => format!("f{}", s.width * 8),
        naga::ScalarKind::Uint => format!("u{}", s.width * 8),
        naga::ScalarKind::Sint => format!("i{}", s.width * 8),
        _ => format!("{:?}", s.kind),
    }
}

/// The uniform and storage structs' layouts: size and members with their offsets.
fn describe_structs(module: &naga::Module, out: &mut BTreeMap<String, Value>) {
    for (_, t) in module.types.iter() {
        let (Some(name), TypeInner::Struct { members, span }) = (&t.name, &t.inner) else { continue };
        if members.iter().any(|m| m.binding.is_some()) {
            continue; // shader stage inputs and outputs, not memory layouts
        }
        out.entry(name.clone()).or_insert_with(|| {
            json!({
                "size": span,
                "members": members.iter().map(|m| json!({
                    "name": m.name,
                    "offset": m.offset,
                    "type": type_name(module, m.ty),
                })).collect::<Vec<_>>(),
            })
        });
    }
}
