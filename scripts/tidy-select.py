#!/usr/bin/env python3
"""The sources scripts/check-tidy --changed tidies (see its header for why).

    tidy-select.py ROOT BUILD_DIR DEPS_FILE < changed paths (relative to ROOT, one a line)

prints the sources of the build's compile_commands.json to tidy, relative to ROOT: the changed
.cpp files, and for each changed header its includers in its own component (from DEPS_FILE, the
output of `ninja -t deps`), else its first includer anywhere, else (no dependencies recorded, e.g.
an unbuilt tree) every source of its component.
"""

import json
import os
import sys

HEADER_EXTS = (".hpp", ".h", ".hpp.in")


def component(path):
    """shared/geometry/include/hq/geometry/x.hpp -> shared/geometry; tests/a/x.hpp -> tests/a."""
    parts = path.split("/")
    for i, part in enumerate(parts):
        if part in ("include", "src", "test", "apps") and i > 0:
            return "/".join(parts[:i])
    return os.path.dirname(path)


def read_deps(deps_file, build_dir, root):
    """{source: set(headers)}, paths relative to root, ours only."""
    includes = {}
    source = None
    with open(deps_file, encoding="utf-8", errors="replace") as f:
        for line in f:
            if not line.startswith("    "):  # an object line starts a block
                source = None
                continue
            path = os.path.relpath(os.path.normpath(os.path.join(build_dir, line.strip())), root)
            if path.startswith(".."):
                continue
            if source is None:  # the first dependency is the source itself
                source = path
                includes.setdefault(source, set())
            else:
                includes[source].add(path)
    return includes


def main():
    root, build_dir, deps_file = (os.path.abspath(a) for a in sys.argv[1:4])
    with open(os.path.join(build_dir, "compile_commands.json"), encoding="utf-8") as f:
        sources = sorted({os.path.relpath(e["file"], root) for e in json.load(f)})
    sources = [s for s in sources if not s.startswith("..") and s.endswith(".cpp")]
    known = set(sources)
    includes = read_deps(deps_file, build_dir, root) if os.path.exists(deps_file) else {}

    chosen = set()
    for path in (line.strip() for line in sys.stdin):
        if not path:
            continue
        if path in known:
            chosen.add(path)
        elif path.endswith(HEADER_EXTS):
            comp = component(path)
            includers = sorted(s for s, hs in includes.items() if path in hs and s in known)
            local = [s for s in includers if s.startswith(comp + "/")]
            if local:
                chosen.update(local)
            elif includers:
                chosen.add(includers[0])
            else:
                chosen.update(s for s in sources if s.startswith(comp + "/"))
    for s in sorted(chosen):
        print(os.path.join(root, s))


if __name__ == "__main__":
    main()
