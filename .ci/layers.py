#!/usr/bin/env python3
"""Layers and laws: a tidy check of src/'s imports (issue 58).

On the code of src/**/*.rs (comments, doc comments and strings left out,
tests included), with ARCHITECTURE.md's "## Layers" table (the entry at the
top) and the laws (shaders/' folders but engine and shared):

1. No `crate::X` (`pidm::X` in src/main.rs) names a module of a layer above
   the file's own; every file but lib.rs is in a module of the table.
2. No `crate::laws::<law>`, `crate::gpu::<law>` outside that law's folders
   src/laws/<law>/ and src/gpu/<law>/ but in ALLOW; none from another law's.
3. No include_str! in a law's folders reads another law's shaders/.
4. No file outside src/laws/ but in ALLOW names a law (`is_lugre`,
   `.karnopp()`, `FrictionLaw::`, `Law::Lugre`, `Friction::Karnopp`, ...).

Why: imports point down the table only, and a third law should touch its
three folders and the ALLOW files, nothing else. Breaks of rule 2 or 4 in
DEBT's files are warnings; DEBT only shrinks (a clean DEBT file fails).

Usage: python3 .ci/layers.py [ROOT] [--verbose] | --self-test
"""

import os
import re
import shutil
import sys
import tempfile
from collections import Counter
from types import SimpleNamespace

# The files outside a law's folders that may name a law: ARCHITECTURE.md's
# "adding a law" checklist, at most 6 files (issue 58).
ALLOW = [
    "src/laws/law.rs",
    "src/laws/mod.rs",
    "src/gpu/mod.rs",
    "src/model/mod.rs",
    "src/scene/keys.rs",
    "src/backend/gpu.rs",
]

# The files that break rule 2 or 4 today: warnings, not errors. It only
# shrinks: a file here that breaks neither fails the check.
DEBT: dict = {}

# Shader includes across laws kept for now (rule 3), each with its reason;
# an entry no longer needed fails the check, as DEBT's do.
INCLUDE_DEBT: dict = {}

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NOT_LAWS = {"engine", "shared"}
LITERAL = re.compile(
    r"(//[^\n]*|/\*.*?\*/)"  # a comment, doc comments too
    r'|(?<!\w)[bc]?r(#*)".*?"\2|[bc]?"(?:\\.|[^"\\])*"'  # a string
    r"|b?'(?:\\(?:x\w\w|u\{\w*\}|.)|[^\\'\n])'",  # a char, not a lifetime
    re.DOTALL,
)
INCLUDE = re.compile(r'include_str!\s*\(\s*"([^"]*)"')
IDENT = re.compile(r"\s*([A-Za-z_]\w*|\*)")
MORE = re.compile(r"\s*::\s*(?!<)")
OPEN, CLOSE, NEXT = re.compile(r"\s*\{"), re.compile(r"\s*\}"), re.compile(r"\s*(as\s+\w+)?\s*,?")


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def strip(text, keep_strings=False):
    """text with comments (and strings) blanked, its lines kept."""

    def blank(m):
        keep = keep_strings and not m.group(1)
        return m.group() if keep else re.sub(r"[^\n]", " ", m.group())

    return LITERAL.sub(blank, text)


def use_tree(code, i):
    """The paths at code[i:] (`a::b`, `{a, b::{c, d}}`): lists of (name, offset)."""
    if m := OPEN.match(code, i):
        paths, i = [], m.end()
        while i < len(code) and not CLOSE.match(code, i):
            sub, j = use_tree(code, i)
            paths += [p for p in sub if p]
            i = max(NEXT.match(code, j).end(), i + 1)
        return paths, i
    if not (m := IDENT.match(code, i)):
        return [[]], i
    head = [(m.group(1), m.start(1))]
    if more := MORE.match(code, m.end()):
        subs, k = use_tree(code, more.end())
        return [head + s for s in subs], k
    return [head], m.end()


def crate_paths(code, is_main):
    """Every `crate::` path (`pidm::` too in main.rs) in code."""
    root = r"\b(?:crate|pidm)::" if is_main else r"\bcrate::"
    return [p for m in re.finditer(root, code) for p in use_tree(code, m.end())[0] if p]


def layer_table(root):
    """{module: layer index} and the layers' names, from ARCHITECTURE.md."""
    section = read(os.path.join(root, "ARCHITECTURE.md")).split("\n## Layers\n", 1)[1]
    rows = [r for r in section.split("\n## ", 1)[0].splitlines() if r.startswith("|")]
    index, names = {}, []
    for row in rows[2:]:
        cells = [c.strip() for c in row.strip("|").split("|")]
        names.append(cells[0])
        for module in re.findall(r"`([^`]+)`", cells[1]):
            if module.endswith(("/", ".rs")) and os.path.exists(os.path.join(root, "src", module)):
                index[module] = len(names) - 1
    return index, names


def module_of(rel):
    """The top-level module of src/...: `gpu/`, `profile.rs`."""
    parts = rel.split("/")[1:]
    return parts[0] + "/" if len(parts) > 1 else parts[0]


def law_of(rel, laws):
    """The law whose folders hold rel, or None."""
    for law in laws:
        if rel.startswith((f"src/laws/{law}/", f"src/gpu/{law}/")):
            return law
    return None


def line(code, offset):
    return code.count("\n", 0, offset) + 1


def check_imports(rel, code, ctx):
    """Rules 1 and 2: (errors, law hits, cross-law hits, number of paths)."""
    errors, hits, cross = [], [], []
    mine, own_law = ctx.index.get(module_of(rel)), law_of(rel, ctx.laws)
    if mine is None and rel != "src/lib.rs":
        errors.append(f"{rel}:1: module {module_of(rel)} is not in ARCHITECTURE.md's Layers table")
    paths = crate_paths(code, rel == "src/main.rs")
    for path in paths:
        (top, at), law = path[0], path[1][0] if len(path) > 1 else None
        dir_ = os.path.isdir(os.path.join(ctx.root, "src", top))
        target = ctx.index.get(top + ("/" if dir_ else ".rs"))
        if mine is not None and target is not None and target < mine:
            errors.append(
                f"{rel}:{line(code, at)}: imports crate::{top} "
                f"(layer '{ctx.names[target]}') from layer '{ctx.names[mine]}', up the table"
            )
        if top not in ("laws", "gpu") or law not in ctx.laws or own_law == law:
            continue
        what = f"{rel}:{line(code, path[1][1])}: imports crate::{top}::{law}"
        if own_law:
            cross.append(f"{what} from law '{own_law}''s folders")
        else:
            hits.append(f"{what} from outside its folders")
    return errors, hits, cross, len(paths)


def check_includes(rel, lit, ctx):
    """Rule 3: a law's folders include_str! no other law's shaders."""
    errors, own_law = [], law_of(rel, ctx.laws)
    for m in INCLUDE.finditer(lit):
        path = os.path.normpath(os.path.join(os.path.dirname(rel), m.group(1)))
        parts = path.replace(os.sep, "/").split("/")
        law = parts[1] if len(parts) > 2 and parts[0] == "shaders" else None
        if own_law and law in ctx.laws and law != own_law:
            if (rel, "/".join(parts)) in INCLUDE_DEBT:
                ctx.included.add((rel, "/".join(parts)))
                continue
            errors.append(
                f"{rel}:{line(lit, m.start())}: includes {'/'.join(parts)} "
                f"(law '{law}') from law '{own_law}''s folders"
            )
    return errors


def check_file(rel, ctx):
    """This file's errors, law hits, cross-law hits (rules 2, 4) and imports."""
    text = read(os.path.join(ctx.root, rel))
    code = strip(text)
    errors, hits, cross, imports = check_imports(rel, code, ctx)
    errors += check_includes(rel, strip(text, keep_strings=True), ctx)
    if not rel.startswith("src/laws/"):
        hits += [
            f"{rel}:{line(code, m.start())}: names a law: {m.group()}" for m in ctx.named(code)
        ]
    return ordered(errors), ordered(hits), ordered(cross), imports


def ordered(messages):
    """messages once each, by line."""
    return sorted(dict.fromkeys(messages), key=lambda m: int(m.split(":")[1]))


def context(root):
    """What every file's check needs: the layers, the laws, a law's names."""
    shaders = os.path.join(root, "shaders")
    laws = sorted(d for d in os.listdir(shaders) if os.path.isdir(os.path.join(shaders, d)))
    laws = [law for law in laws if law not in NOT_LAWS]
    lower, caps = "|".join(laws), "|".join(law.capitalize() for law in laws)
    named = re.compile(
        rf"\bis_(?:{lower})\b|\.(?:{lower})\(\)|\bFrictionLaw::|\b(?:Law|Friction)::(?:{caps})\b"
    )
    index, names = layer_table(root)
    return SimpleNamespace(
        root=root, index=index, names=names, laws=laws, named=named.finditer, included=set()
    )


def check(root):
    """(errors, warnings, summary) for the repository at root."""
    ctx, errors, warnings, files, imports = context(root), [], [], [], 0
    for dirpath, _, filenames in sorted(os.walk(os.path.join(root, "src"))):
        for name in sorted(f for f in filenames if f.endswith(".rs")):
            rel = os.path.relpath(os.path.join(dirpath, name), root).replace(os.sep, "/")
            errs, hits, cross, n = check_file(rel, ctx)
            files, imports, errors = files + [rel], imports + n, errors + errs
            if rel in DEBT:
                warnings += hits + cross
            else:
                errors += cross if rel in ALLOW else hits + cross
    for rel, path in sorted(set(INCLUDE_DEBT) - ctx.included):
        errors.append(f"{rel} no longer includes {path}: remove it from INCLUDE_DEBT")
    clean = [r for r in DEBT if r not in files or not any(w.startswith(r + ":") for w in warnings)]
    errors += [f"{r} is clean now: remove it from DEBT in .ci/layers.py" for r in sorted(clean)]
    if len(ALLOW) > 6:
        errors.append(f"ALLOW holds {len(ALLOW)} files, more than 6 (issue 58)")
    summary = f"layers: {len(files)} files, {imports} imports, {len(DEBT)} debt files"
    return errors, warnings, summary


def self_test():
    """Plant two violations in a copy of the tree; 0 if both are reported."""
    with tempfile.TemporaryDirectory() as tmp:
        for part in ("src", "shaders"):
            shutil.copytree(os.path.join(ROOT, part), os.path.join(tmp, part))
        shutil.copy(os.path.join(ROOT, "ARCHITECTURE.md"), tmp)
        model, lugre = (
            d + "/" + min(f for f in os.listdir(os.path.join(tmp, d)) if f.endswith(".rs"))
            for d in ("src/model", "src/laws/lugre")
        )
        for rel, planted in (
            (model, "use crate::commands::run;"),
            (lugre, 'const _: &str = include_str!("../../../shaders/karnopp/measure.wgsl");'),
        ):
            text = read(os.path.join(tmp, rel))
            with open(os.path.join(tmp, rel), "w", encoding="utf-8") as f:
                f.write(planted + "\n" + text)
        errors = check(tmp)[0]
    wanted = [
        f"{model}:1: imports crate::commands (layer 'entry') from layer 'model', up the table",
        f"{lugre}:1: includes shaders/karnopp/measure.wgsl (law 'karnopp') from law 'lugre''s folders",
    ]
    print("".join(("found: " if w in errors else "MISSED: ") + w + "\n" for w in wanted), end="")
    ok = all(w in errors for w in wanted)
    print("layers self-test: " + ("OK" if ok else "FAILED"))
    return 0 if ok else 1


def main(argv):
    if "--self-test" in argv:
        return self_test()
    errors, warnings, summary = check(([a for a in argv if a[0] != "-"] + [ROOT])[0])
    debt = sorted(Counter(w.split(":")[0] for w in warnings).items())
    if "--verbose" not in argv:
        warnings = [f"{rel}: {n} in DEBT, {DEBT[rel]}" for rel, n in debt]
    print("".join(f"warning: {w}\n" for w in warnings) + "".join(e + "\n" for e in errors), end="")
    print(f"{summary}, {len(errors)} errors" if errors else f"{summary}, OK")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
