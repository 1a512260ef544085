"""Replaces a generated block of a Markdown file, the text between its `<!-- NAME:begin -->` and
`<!-- NAME:end -->` lines, atomically (the file is never left half written)."""

import os
import sys


def replace_block(path, name, text):
    with open(path) as f:
        doc = f.read()
    begin, end = f"<!-- {name}:begin -->\n", f"<!-- {name}:end -->"
    if begin not in doc or end not in doc:
        sys.exit(f"{path}: no '{begin.strip()}' ... '{end}' lines to replace")
    head, rest = doc.split(begin, 1)
    tail = rest.split(end, 1)[1]
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(head + begin + text + end + tail)
    os.replace(tmp, path)
