"""Shared by the output checks (check_markdown.py, check_latex.py): the files to check."""

import pathlib
import sys


def files_in(paths, suffix, prog):
    """Every `suffix` file under the given folders (recursively) and the files given, in
    order; exits 2 with a message on a missing path or when there is nothing to check."""
    files = []
    for a in paths:
        p = pathlib.Path(a)
        if p.is_dir():
            files += sorted(p.rglob(f"*{suffix}"))
        elif p.is_file():
            files.append(p)
        else:
            print(f"{prog}: {p}: no such file or folder", file=sys.stderr)
            sys.exit(2)
    if not files:
        print(f"{prog}: no {suffix} file in {' '.join(map(str, paths))}", file=sys.stderr)
        sys.exit(2)
    return files
