"""Bazel rules for furbake: bake glTF assets into fur and grass packs as build actions.

Load from a workspace that has this file (a copy, `local_repository` or `http_archive` of the
furbake repository):

    load("@furbake//bazel:furbake.bzl", "furbake_pack", "furbake_packs")

    furbake_pack(
        name = "fox",
        src = "models/Fox.glb",
        preset = "fur",
        topologies = ["prisms"],
        settings = {"volume.resolution": "64"},
        furbake = "//tools:furbake",     # the furbake executable (see below)
    )

`furbake` is any executable label: a prebuilt binary checked in or fetched (`exports_files`), or
the `furbake-cli` crate built by the workspace's own Rust rules (rules_rust's `rust_binary`).
Every action declares exactly what it reads — the glTF, the buffers and textures it names
(`srcs`), the config — so a sandboxed action (`--spawn_strategy=sandboxed`) cannot read anything
else, and the pack is a pure function of those inputs: the same bytes on any machine, which is
what lets a remote cache or remote execution service (`--remote_cache=`, `--remote_executor=`)
hand a pack baked elsewhere to every other machine.
"""

def _furbake_pack_impl(ctx):
    out = ctx.actions.declare_file(ctx.attr.out or (ctx.label.name + ".fbk"))
    outputs = [out]
    args = ctx.actions.args()
    args.add("bake")
    args.add(ctx.file.src)
    args.add("-o", out)
    args.add("--preset", ctx.attr.preset)
    args.add("--quiet")
    # A buffer or texture missing from `srcs` is then an error naming it, never a pack without it.
    args.add("--strict-inputs")
    inputs = [ctx.file.src] + ctx.files.srcs
    if ctx.file.config:
        args.add("--config", ctx.file.config)
        inputs.append(ctx.file.config)
    for topology in ctx.attr.topologies:
        args.add("--topology", topology)
    for key in sorted(ctx.attr.settings.keys()):
        args.add("--set", "%s=%s" % (key, ctx.attr.settings[key]))
    if ctx.attr.report:
        report = ctx.actions.declare_file(ctx.label.name + ".report.json")
        args.add("--report", report)
        outputs.append(report)
    ctx.actions.run(
        executable = ctx.executable.furbake,
        arguments = [args],
        inputs = inputs,
        outputs = outputs,
        mnemonic = "FurbakePack",
        progress_message = "Baking %s" % out.short_path,
    )
    return [DefaultInfo(files = depset(outputs))]

furbake_pack = rule(
    implementation = _furbake_pack_impl,
    doc = "Bakes one glTF asset into a furbake pack (`furbake bake`).",
    attrs = {
        "src": attr.label(allow_single_file = [".glb", ".gltf"], mandatory = True, doc = "The glTF."),
        "srcs": attr.label_list(allow_files = True, doc = "Every external buffer and image the glTF names."),
        "out": attr.string(doc = "The pack's file name (default: NAME.fbk)."),
        "preset": attr.string(default = "fur", values = ["fur", "grass"]),
        "config": attr.label(allow_single_file = [".toml"], doc = "A bake config (`--config`)."),
        "topologies": attr.string_list(doc = "Mass-spring topologies to bake (`--topology`)."),
        "settings": attr.string_dict(doc = "Setting overrides, dotted key to value (`--set KEY=VALUE`)."),
        "report": attr.bool(default = False, doc = "Also write NAME.report.json (`--report`)."),
        "furbake": attr.label(executable = True, cfg = "exec", allow_files = True, mandatory = True),
    },
)

def furbake_packs(name, srcs, furbake, data = [], **kwargs):
    """One `furbake_pack` per glTF in `srcs` (named after the file), and a filegroup `name` of
    them all. `data` lists the buffers and images the glTFs name (every pack's action gets them
    all: a glTF reading another's files is not refused, but then touching one rebakes both)."""
    packs = []
    for src in srcs:
        stem = src.rsplit("/", 1)[-1].rsplit(".", 1)[0]
        furbake_pack(name = stem, src = src, srcs = data, furbake = furbake, **kwargs)
        packs.append(":" + stem)
    native.filegroup(name = name, srcs = packs)
