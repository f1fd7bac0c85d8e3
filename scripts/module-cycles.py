#!/usr/bin/env python3
"""Import cycles between the modules of a Rust crate, read from its `crate::` and `super::` paths.

Usage: scripts/module-cycles.py SRC_DIR [MODULE_PREFIX]
  e.g. scripts/module-cycles.py server/src        (the server's floors and api/)
       scripts/module-cycles.py synth/src models  (every model folder)

Test modules (`#[cfg(test)]` onwards) and comments are left out; a module's declaration of its
children is not an import, and a path names the longest module it starts with. Prints the
cycles and exits 1 when there is one.
"""
import glob
import os
import re
import sys

src, prefix = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else "")
os.chdir(src)


def module(path):
    parts = path[:-3].split("/")
    if parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return "::".join(parts)


files = {module(f): f for f in glob.glob("**/*.rs", recursive=True)}


def longest_module(parts):
    for k in range(len(parts), 0, -1):
        name = "::".join(parts[:k])
        if name in files:
            return name
    return None


def imports(name, path):
    text = open(path).read()
    text = text[: text.find("#[cfg(test)]")] if "#[cfg(test)]" in text else text
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"pub\(in crate::[a-z_:]+\)", "pub", text)
    here = name.split("::") if name else []
    found = set()
    for m in re.finditer(r"\bcrate::([a-z_]+(?:::[a-z_]+)*)", text):
        found.add(longest_module(m.group(1).split("::")))
    for m in re.finditer(r"\bsuper::([a-z_]+(?:::[a-z_]+)*)", text):
        found.add(longest_module(here[:-1] + m.group(1).split("::")))
    return {d for d in found if d and d != name and not d.startswith(name + "::") and d.startswith(prefix)}


graph = {n: imports(n, f) for n, f in files.items() if n.startswith(prefix)}

# Tarjan's strongly connected components: a component of more than one module is a cycle.
index, low, stack, on_stack, cycles = {}, {}, [], set(), []
sys.setrecursionlimit(10000)


def visit(v):
    index[v] = low[v] = len(index)
    stack.append(v)
    on_stack.add(v)
    for w in graph.get(v, ()):
        if w not in index:
            visit(w)
            low[v] = min(low[v], low[w])
        elif w in on_stack:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        component = []
        while True:
            w = stack.pop()
            on_stack.discard(w)
            component.append(w)
            if w == v:
                break
        if len(component) > 1:
            cycles.append(sorted(component))


for v in sorted(graph):
    if v not in index:
        visit(v)
for c in cycles:
    print("cycle:", " ↔ ".join(c))
print(f"{len(graph)} modules, {len(cycles)} cycles")
sys.exit(1 if cycles else 0)
