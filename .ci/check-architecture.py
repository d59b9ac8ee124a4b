#!/usr/bin/env python3
"""Architecture checks on the source tree (no build needed), for what Cargo cannot check.

1. Layering within a crate: no module imports from a layer above its own (the layers are in
   .ci/layers.toml). Between crates Cargo enforces it: duocan-core (layers 0 to 7) does not
   depend on duocan (8 to 11), duocan-redundancy-core (the redundancy's layers 0 to 3) depends
   on duocan-core alone, not on duocan-redundancy (4 and 5) nor duocan, and the duocan library
   does not depend on duocan-redundancy (a dev-dependency of its tests and examples only), so
   an upward import across crates does not compile (the two core crates' docs hold
   `compile_fail` doctests that prove it). This script only sees `crate::` paths, so it checks
   each crate's own modules.
2. Dependencies Cargo would accept: a crate's manifest lists none of its `not_depends_on`
   (.ci/layers.toml) among its dependencies (development dependencies, which only tests and
   examples see, may). A dependency on a crate above would not be a cycle where that crate
   depends on this one only for its tests, so Cargo would not refuse it.
3. Names: no two public types (struct, enum, trait, type alias, union) share a name across the
   crates, so a user who reads a type name knows which type it is.

Test code (`#[cfg(test)]` modules, `tests/` folders inside src) and comments are not checked:
tests may reach across layers to set things up. Prints each violation with file and line.
"""
import pathlib
import re
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent


def code_lines(path):
    """(line number, text) of a file's non-test, non-comment code."""
    out = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if re.match(r"\s*#\[cfg\(test\)\]", line):
            break  # test modules stand at the end of a file
        line = re.sub(r"//.*", "", line)
        if line.strip():
            out.append((n, line))
    return out


def module_of(path, src):
    rel = path.relative_to(src)
    return rel.parts[0].removesuffix(".rs")


def imports(text, crate):
    """Top-level modules named after `crate::` (also inside `crate::{a, b::c}`)."""
    found = set(re.findall(r"\bcrate::([A-Za-z_]\w*)", text))
    for group in re.findall(r"\bcrate::\{([^}]*)", text):
        found.update(re.findall(r"(?:^|,)\s*([A-Za-z_]\w*)", group))
    return found


def reexports(src):
    """Names the crate root re-exports (`pub use module::...::{A, b}`), mapped to their module, so
    that `crate::A` counts as an import from that module's layer."""
    text = "\n".join(t for _, t in code_lines(src / "lib.rs"))
    found = {}
    for module, rest in re.findall(r"pub use (\w+)::([^;]*);", text, re.S):
        for name in re.findall(r"\b(\w+)\b(?:\s*,|\s*}|\s*$)", rest):
            found[name] = module
    return found


def check_layers(cfg):
    errors = []
    for c in cfg["crate"]:
        src = ROOT / c["src"]
        # Layers are numbered across crates: a crate above another starts at `first_layer`.
        rank = {m: i for i, layer in enumerate(c["layers"], c.get("first_layer", 0)) for m in layer}
        aliases = reexports(src)
        for name, module in aliases.items():
            if module in rank and name not in rank:
                rank[name] = rank[module]
        for path in sorted(src.rglob("*.rs")):
            if "tests" in path.relative_to(src).parts[:-1]:
                continue
            mod = module_of(path, src)
            if mod == "lib":
                continue
            if mod not in rank:
                errors.append(f"{path.relative_to(ROOT)}: module `{mod}` is in no layer of .ci/layers.toml")
                continue
            # Whole-file text so that multi-line `use crate::{...}` groups are seen.
            lines = code_lines(path)
            text = "\n".join(t for _, t in lines)
            for target in sorted(imports(text, c["name"])):
                if target in rank and rank[target] > rank[mod]:
                    line = next((n for n, t in lines if f"crate::{target}" in t or re.search(rf"\b{target}\b", t) and "crate::{" in t), "?")
                    errors.append(
                        f"{path.relative_to(ROOT)}:{line}: `{mod}` (layer {rank[mod]}) imports `{target}` (layer {rank[target]}, above it)"
                    )
    return errors


def check_dependencies(cfg):
    errors = []
    for c in cfg["crate"]:
        if "not_depends_on" not in c:
            continue
        manifest = tomllib.loads((ROOT / c["manifest"]).read_text())
        tables = [manifest.get("dependencies", {}), manifest.get("build-dependencies", {})]
        tables += [t.get("dependencies", {}) for t in manifest.get("target", {}).values()]
        for deps in tables:
            for key, spec in deps.items():
                name = spec.get("package", key) if isinstance(spec, dict) else key
                if name in c["not_depends_on"]:
                    errors.append(f"{c['manifest']}: `{c['name']}` depends on `{name}`, a crate above it")
    return errors


PUB_TYPE = re.compile(r"^\s*pub\s+(?:struct|enum|trait|type|union)\s+([A-Z][A-Za-z0-9_]*)")


def check_names(cfg):
    seen = {}
    for c in cfg["crate"]:
        src = ROOT / c["src"]
        for path in sorted(src.rglob("*.rs")):
            if "tests" in path.relative_to(src).parts[:-1]:
                continue
            for n, line in code_lines(path):
                m = PUB_TYPE.match(line)
                if m:
                    seen.setdefault(m.group(1), []).append(f"{path.relative_to(ROOT)}:{n}")
    # Declarations of one name in one file are cfg alternatives of one type.
    files = {name: {a.split(":")[0] for a in at} for name, at in seen.items()}
    return [
        f"public type `{name}` is declared in {len(files[name])} places: {', '.join(at)}"
        for name, at in sorted(seen.items())
        if len(files[name]) > 1
    ]


def main():
    cfg = tomllib.loads((ROOT / ".ci" / "layers.toml").read_text())
    errors = check_layers(cfg) + check_dependencies(cfg) + check_names(cfg)
    for e in errors:
        print(e)
    if errors:
        print(f"architecture check: {len(errors)} problem(s)")
        return 1
    print("architecture check: layering, dependencies and public type names are clean")
    return 0


if __name__ == "__main__":
    sys.exit(main())
