#!/usr/bin/env python3
"""Fails when a workspace crate declares a dependency its code never names, or the workspace
declares one no crate uses. A dependency kept for a reason other than its name in code (a
feature it switches on, a library it links) is listed in the crate's
`[package.metadata.check-deps] keep = ["name"]` with a comment saying why."""
import pathlib, re, sys, tomllib

root = pathlib.Path(__file__).resolve().parent.parent
ws = tomllib.loads((root / "Cargo.toml").read_text())
used_anywhere, problems = set(), []

def sources(crate, kinds):
    dirs = {"normal": ["src"], "dev": ["src", "tests", "benches", "examples"], "build": []}
    files = [crate / "build.rs"] if kinds == "build" else []
    for d in dirs[kinds]:
        files += sorted((crate / d).rglob("*.rs"))
    return "\n".join(f.read_text() for f in files if f.is_file())

for member in ws["workspace"]["members"]:
    crate = root / member
    manifest = tomllib.loads((crate / "Cargo.toml").read_text())
    keep = set(manifest.get("package", {}).get("metadata", {}).get("check-deps", {}).get("keep", []))
    for section, kinds in [("dependencies", "normal"), ("dev-dependencies", "dev"),
                           ("build-dependencies", "build")]:
        text = None
        for name, spec in manifest.get(section, {}).items():
            used_anywhere.add(spec.get("package", name) if isinstance(spec, dict) else name)
            if name in keep:
                continue
            text = sources(crate, kinds) if text is None else text
            named = lambda t: re.search(r"\b" + re.escape(name.replace("-", "_")) + r"\b", t)
            if named(text):
                continue
            where = "named only by its tests: move it to [dev-dependencies]" if (
                kinds == "normal" and named(sources(crate, "dev"))) else "never named in its code"
            problems.append(f"{member}/Cargo.toml [{section}] {name}: {where}")

for name in ws["workspace"].get("dependencies", {}):
    if name not in used_anywhere:
        problems.append(f"Cargo.toml [workspace.dependencies] {name}: no crate uses it")

for p in problems:
    print(f"check-deps: {p}", file=sys.stderr)
sys.exit(1 if problems else 0)
