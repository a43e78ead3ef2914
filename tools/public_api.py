#!/usr/bin/env python3
"""Lists a crate's public API from rustdoc's JSON output, one item a line, sorted.

    python3 tools/public_api.py target/doc/furbake_render.json > docs/api/furbake-render.txt

The JSON comes from `cargo rustdoc -p CRATE --lib -- -Z unstable-options --output-format json`
(RUSTC_BOOTSTRAP=1 lets the stable toolchain write it; `make api` does both steps). Every item a
user of the crate can name is listed under the path they name it by: modules, re-exports
(resolved to what they point at where that is in the crate), structs with their public fields,
enums with their variants, traits, functions with their signatures, constants, type aliases, and
the inherent methods and trait implementations of every listed type. Items that are
`#[doc(hidden)]` are left out, as rustdoc leaves them out of the documentation. The listing is
what `make api-check` compares with the committed snapshot (docs/api/), so that a change to the
public surface is a reviewed change to that file.

Exit codes: 0 listed, 2 unreadable input or an unsupported rustdoc JSON format.
"""

import json
import sys

# rustdoc's JSON changes shape between toolchains; these are the versions this script reads.
MIN_FORMAT, MAX_FORMAT = 39, 60


def main(argv):
    if len(argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    try:
        with open(argv[1], encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, ValueError) as e:
        print(f"{argv[1]}: {e}", file=sys.stderr)
        return 2
    version = doc.get("format_version", 0)
    if not MIN_FORMAT <= version <= MAX_FORMAT:
        print(f"{argv[1]}: rustdoc JSON format {version}, this script reads {MIN_FORMAT}..={MAX_FORMAT}", file=sys.stderr)
        return 2
    lines = set()
    Lister(doc, lines).module(doc["root"], [], set())
    sys.stdout.write("".join(f"{line}\n" for line in sorted(lines)))
    return 0


def inner_kind(item):
    (kind,) = item["inner"].keys()
    return kind, item["inner"][kind]


def hidden(item):
    attrs = item.get("attrs") or []
    return any("doc(hidden)" in (a if isinstance(a, str) else json.dumps(a)).replace(" ", "") for a in attrs)


class Lister:
    def __init__(self, doc, lines):
        self.doc = doc
        self.index = doc["index"]
        self.paths = doc.get("paths", {})
        self.lines = lines

    def item(self, id_):
        return self.index.get(str(id_))

    def module(self, id_, path, seen):
        if id_ in seen:
            return
        seen = seen | {id_}
        item = self.item(id_)
        _, module = inner_kind(item)
        for child_id in module["items"]:
            child = self.item(child_id)
            if child is None or child["visibility"] != "public" or hidden(child):
                continue
            kind, inner = inner_kind(child)
            if kind in ("use", "import"):
                self.use(child, inner, path, seen)
            else:
                self.named(child_id, child, path + [child["name"]], seen)

    def use(self, item, inner, path, seen):
        target = self.item(inner["id"]) if inner.get("id") is not None else None
        if inner.get("is_glob"):
            if target is not None and inner_kind(target)[0] == "module":
                self.module(inner["id"], path, seen)
            else:
                self.lines.add(f"pub use {'::'.join(path + ['*'])} = {inner['source']}::*")
            return
        name = inner["name"]
        if target is None or hidden(target):
            # Re-exported from another crate: name it and its source, not its insides.
            self.lines.add(f"pub use {'::'.join(path + [name])} = {inner['source']}")
            return
        self.named(inner["id"], target, path + [name], seen)

    def named(self, id_, item, path, seen):
        kind, inner = inner_kind(item)
        full = "::".join(path)
        if kind == "module":
            self.lines.add(f"pub mod {full}")
            self.module(id_, path, seen)
        elif kind == "struct":
            generics = self.generics(inner.get("generics"))
            self.lines.add(f"pub struct {full}{generics}")
            fields = inner.get("kind", {})
            if isinstance(fields, dict) and "plain" in fields:
                for fid in fields["plain"].get("fields", []):
                    field = self.item(fid)
                    if field and field["visibility"] == "public" and not hidden(field):
                        self.lines.add(f"pub {full}::{field['name']}: {self.ty(inner_kind(field)[1])}")
            elif isinstance(fields, dict) and "tuple" in fields:
                for i, fid in enumerate(fields["tuple"]):
                    field = self.item(fid) if fid is not None else None
                    if field and field["visibility"] == "public" and not hidden(field):
                        self.lines.add(f"pub {full}::{i}: {self.ty(inner_kind(field)[1])}")
            self.impls(inner.get("impls", []), full)
        elif kind == "enum":
            self.lines.add(f"pub enum {full}{self.generics(inner.get('generics'))}")
            for vid in inner.get("variants", []):
                variant = self.item(vid)
                if variant and not hidden(variant):
                    self.lines.add(f"pub {full}::{variant['name']}{self.variant(inner_kind(variant)[1])}")
            self.impls(inner.get("impls", []), full)
        elif kind == "function":
            self.lines.add(f"pub fn {full}{self.signature(inner)}")
        elif kind == "constant":
            ty = inner.get("type") if "type" in inner else inner.get("const", {}).get("type")
            self.lines.add(f"pub const {full}: {self.ty(ty)}")
        elif kind == "static":
            self.lines.add(f"pub static {full}: {self.ty(inner.get('type'))}")
        elif kind == "type_alias":
            self.lines.add(f"pub type {full} = {self.ty(inner.get('type'))}")
        elif kind == "trait":
            self.lines.add(f"pub trait {full}")
            for mid in inner.get("items", []):
                member = self.item(mid)
                if member and not hidden(member):
                    self.lines.add(f"pub {self.member(member, full)}")
        elif kind == "macro":
            self.lines.add(f"pub macro {full}!")
        else:
            self.lines.add(f"pub {kind} {full}")

    def impls(self, impl_ids, owner):
        for iid in impl_ids:
            impl = self.item(iid)
            if impl is None or hidden(impl):
                continue
            _, inner = inner_kind(impl)
            if inner.get("blanket_impl") is not None or inner.get("is_synthetic") or inner.get("synthetic"):
                continue
            trait = inner.get("trait")
            if trait is not None:
                self.lines.add(f"impl {self.path(trait)} for {owner}")
                continue
            for mid in inner.get("items", []):
                member = self.item(mid)
                if member and member["visibility"] == "public" and not hidden(member):
                    self.lines.add(f"pub {self.member(member, owner)}")

    def member(self, member, owner):
        kind, inner = inner_kind(member)
        name = f"{owner}::{member['name']}"
        if kind == "function":
            return f"fn {name}{self.signature(inner)}"
        if kind == "assoc_const":
            return f"const {name}: {self.ty(inner.get('type'))}"
        if kind == "assoc_type":
            return f"type {name}"
        return f"{kind} {name}"

    def variant(self, inner):
        kind = inner.get("kind")
        if isinstance(kind, dict) and "tuple" in kind:
            types = []
            for fid in kind["tuple"]:
                field = self.item(fid) if fid is not None else None
                types.append(self.ty(inner_kind(field)[1]) if field else "_")
            return f"({', '.join(types)})"
        if isinstance(kind, dict) and "struct" in kind:
            fields = []
            for fid in kind["struct"].get("fields", []):
                field = self.item(fid)
                if field:
                    fields.append(f"{field['name']}: {self.ty(inner_kind(field)[1])}")
            return " { " + ", ".join(fields) + " }"
        return ""

    def signature(self, inner):
        sig = inner.get("sig") or inner.get("decl")
        inputs = []
        for name, ty in sig.get("inputs", []):
            if name == "self":
                inputs.append(self.self_param(ty))
            else:
                inputs.append(f"{name}: {self.ty(ty)}")
        output = sig.get("output")
        ret = f" -> {self.ty(output)}" if output is not None else ""
        return f"{self.generics(inner.get('generics'))}({', '.join(inputs)}){ret}"

    def self_param(self, ty):
        if "borrowed_ref" in ty:
            ref = ty["borrowed_ref"]
            return "&mut self" if ref.get("is_mutable", ref.get("mutable")) else "&self"
        if "generic" in ty and ty["generic"] == "Self":
            return "self"
        return f"self: {self.ty(ty)}"

    def generics(self, generics):
        if not generics:
            return ""
        params = []
        for p in generics.get("params", []):
            kind = p.get("kind", {})
            if "lifetime" in kind:
                params.append(p["name"])
            elif "type" in kind:
                if kind["type"].get("is_synthetic", kind["type"].get("synthetic")):
                    continue
                bounds = [self.bound(b) for b in kind["type"].get("bounds", [])]
                params.append(p["name"] + (": " + " + ".join(bounds) if bounds else ""))
            elif "const" in kind:
                params.append(f"const {p['name']}: {self.ty(kind['const'].get('type'))}")
        return f"<{', '.join(params)}>" if params else ""

    def bound(self, b):
        if "trait_bound" in b:
            return self.path(b["trait_bound"]["trait"])
        if "outlives" in b:
            return b["outlives"]
        return "?"

    def path(self, p):
        name = p.get("path") or p.get("name") or "?"
        args = self.args(p.get("args"))
        return f"{name}{args}"

    def args(self, args):
        if not args:
            return ""
        if "angle_bracketed" in args:
            parts = []
            for a in args["angle_bracketed"].get("args", []):
                if "lifetime" in a:
                    parts.append(a["lifetime"])
                elif "type" in a:
                    parts.append(self.ty(a["type"]))
                elif "const" in a:
                    parts.append(a["const"].get("expr", "_"))
                else:
                    parts.append("_")
            for c in args["angle_bracketed"].get("constraints", args["angle_bracketed"].get("bindings", [])):
                parts.append(f"{c['name']} = …")
            return f"<{', '.join(parts)}>" if parts else ""
        if "parenthesized" in args:
            p = args["parenthesized"]
            out = f" -> {self.ty(p['output'])}" if p.get("output") else ""
            return f"({', '.join(self.ty(t) for t in p.get('inputs', []))}){out}"
        return ""

    def ty(self, t):
        if t is None:
            return "()"
        if "resolved_path" in t:
            return self.path(t["resolved_path"])
        if "primitive" in t:
            return t["primitive"]
        if "generic" in t:
            return t["generic"]
        if "borrowed_ref" in t:
            r = t["borrowed_ref"]
            life = f"{r['lifetime']} " if r.get("lifetime") else ""
            mut = "mut " if r.get("is_mutable", r.get("mutable")) else ""
            return f"&{life}{mut}{self.ty(r['type'])}"
        if "raw_pointer" in t:
            r = t["raw_pointer"]
            return f"*{'mut' if r.get('is_mutable', r.get('mutable')) else 'const'} {self.ty(r['type'])}"
        if "slice" in t:
            return f"[{self.ty(t['slice'])}]"
        if "array" in t:
            return f"[{self.ty(t['array']['type'])}; {t['array']['len']}]"
        if "tuple" in t:
            items = [self.ty(x) for x in t["tuple"]]
            return f"({', '.join(items)}{',' if len(items) == 1 else ''})"
        if "impl_trait" in t:
            return "impl " + " + ".join(self.bound(b) for b in t["impl_trait"])
        if "dyn_trait" in t:
            return "dyn " + " + ".join(self.path(tr["trait"]) for tr in t["dyn_trait"].get("traits", []))
        if "qualified_path" in t:
            q = t["qualified_path"]
            trait = f" as {self.path(q['trait'])}" if q.get("trait") else ""
            return f"<{self.ty(q['self_type'])}{trait}>::{q['name']}"
        if "function_pointer" in t:
            return "fn(…)"
        return "?"


if __name__ == "__main__":
    sys.exit(main(sys.argv))
