#!/usr/bin/env python3
"""Dependencies point down (issue 31): every project include is backed by a CMake link.

Reads the product CMakeLists.txt files (targets, their sources, their target_link_libraries)
and the sources' #include "..." lines, and fails when
  * a file includes a project header whose library its own target does not link, directly
    or through other targets (an include without a link builds only by accident of order);
  * a file under slam_core/, server_runtime/ or runtime_common/ includes tests/ or tools/;
  * a file under slam_core/ includes a Fast DDS header or the generated IDL types.
Headers belong to the target that compiles the .cc of the same name, or else to the
library of their folder. Generated headers (the IDL types) are not checked.
"""
import argparse
import os
import re
import sys

PRODUCT_DIRS = ["slam_core", "runtime_common", "agent_runtime", "server_runtime", "tools", "tests/sim"]
NO_TEST_OR_TOOL_INCLUDES = ["slam_core/", "server_runtime/", "runtime_common/"]
SOURCE_EXT = (".cc", ".cpp", ".h")

TARGET_RE = re.compile(r"add_(library|executable)\(\s*([A-Za-z0-9_]+)([^)]*)\)", re.S)
LINK_RE = re.compile(r"target_link_libraries\(\s*([A-Za-z0-9_]+)([^)]*)\)", re.S)
INCLUDE_RE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
SYSTEM_INCLUDE_RE = re.compile(r"^\s*#\s*include\s+[<\"](fastdds|fastrtps|fastcdr)/", re.M)


def strip_comments(text):
    return "\n".join(line.split("#", 1)[0] for line in text.splitlines())


def read_targets(root):
    """{target: {"dir", "sources", "links", "library"}} for every product CMakeLists.txt."""
    targets = {}
    for top in PRODUCT_DIRS:
        for folder, _, files in os.walk(os.path.join(root, top)):
            if "CMakeLists.txt" not in files:
                continue
            with open(os.path.join(folder, "CMakeLists.txt")) as f:
                text = strip_comments(f.read())
            rel = os.path.relpath(folder, root)
            for kind, name, body in TARGET_RE.findall(text):
                sources = [os.path.normpath(os.path.join(rel, t)) for t in body.split() if t.endswith(SOURCE_EXT)]
                targets[name] = dict(dir=rel, sources=sources, links=set(), library=kind == "library")
            for name, body in LINK_RE.findall(text):
                if name in targets:
                    targets[name]["links"].update(t for t in body.split() if t not in ("PUBLIC", "PRIVATE", "INTERFACE"))
    return targets


def closure(targets, name):
    seen, todo = set(), [name]
    while todo:
        t = todo.pop()
        if t in seen or t not in targets:
            continue
        seen.add(t)
        todo.extend(targets[t]["links"])
    return seen


def owners(targets, path):
    """Targets a project file belongs to: the one compiling it (or its .cc), else its folder's libraries."""
    stem = os.path.splitext(path)[0]
    compiled = [n for n, t in targets.items()
                if path in t["sources"] or any(os.path.splitext(s)[0] == stem for s in t["sources"])]
    if compiled:
        return compiled
    return [n for n, t in targets.items() if t["library"] and t["dir"] == os.path.dirname(path)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    root = os.path.abspath(ap.parse_args().root)
    targets = read_targets(root)
    if "ccm_map" not in targets or "ccm_server_backend" not in targets:
        print("FAIL: could not read the CMake targets under " + root)
        return 1
    problems, checked = [], 0
    for top in PRODUCT_DIRS:
        for folder, _, files in os.walk(os.path.join(root, top)):
            for file in sorted(files):
                if not file.endswith(SOURCE_EXT):
                    continue
                path = os.path.relpath(os.path.join(folder, file), root)
                with open(os.path.join(root, path), errors="replace") as f:
                    text = f.read()
                if path.startswith("slam_core/") and SYSTEM_INCLUDE_RE.search(text):
                    problems.append(f"{path}: slam_core includes Fast DDS")
                mine = owners(targets, path)
                reach = set().union(*(closure(targets, t) for t in mine)) if mine else set()
                for inc in INCLUDE_RE.findall(text):
                    if any(path.startswith(d) for d in NO_TEST_OR_TOOL_INCLUDES) and inc.startswith(("tests/", "tools/")):
                        problems.append(f"{path}: includes {inc} (product code must not depend on tests/ or tools/)")
                        continue
                    if not os.path.exists(os.path.join(root, inc)):
                        continue  # generated (IDL types) or not a project path
                    theirs = owners(targets, inc)
                    checked += 1
                    if theirs and mine and not reach.intersection(theirs):
                        problems.append(f"{path} ({', '.join(mine)}): includes {inc} of {', '.join(theirs)} "
                                        "without linking it")
    for p in problems:
        print("FAIL: " + p)
    print(f"{len(targets)} targets, {checked} project includes checked, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
