#!/usr/bin/python3
"""The built-in phone sets' detection order, wherever the project writes it down, is the engine's.

`--phone-set` absent, the engine tries the built-in sets in the order of kDetectionOrder
(core/src/phone_set.cpp) and takes the first that knows every label. That order is also written in
prose: docs/phone-sets.md (from tools/make_default_model.py), docs/languages.md and the Python
client's docstring. Each list of four or more built-in set names, comma-separated, in the docs, the
tools and the Python client must be that order, whole.

  phone_set_order_test.py [SOURCE_DIR]      (default: the checkout this script is in)

Exit status 0 when every list agrees; 1 with one line per list that does not (file:line: the list).
"""
import os
import re
import sys


def engine_order(source_dir):
    with open(os.path.join(source_dir, "core", "src", "phone_set.cpp")) as source:
        match = re.search(r"kDetectionOrder\[\]\s*=\s*\{([^}]*)\}", source.read())
    return re.findall(r'"([a-z]+)"', match.group(1))


def written_lists(path, names):
    """(line number, [names]) for each run of four or more set names separated by ", " or " and "."""
    name = "(?:" + "|".join(names) + ")"
    run = re.compile(rf"\b{name}(?:(?:, | and |,\n\s*#?\s*\"?){name}){{3,}}\b")
    with open(path, encoding="utf-8") as text:
        content = text.read()
    for found in run.finditer(content):
        yield content.count("\n", 0, found.start()) + 1, re.findall(name, found.group(0))


def main():
    source_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), os.pardir, os.pardir)
    order = engine_order(source_dir)
    assert len(order) >= 4, f"kDetectionOrder not found in core/src/phone_set.cpp: {order}"
    files = [os.path.join("tools", "make_default_model.py")]
    files += [os.path.join("docs", f) for f in sorted(os.listdir(os.path.join(source_dir, "docs"))) if f.endswith(".md")]
    python = os.path.join("clients", "python", "lipsync_client")
    files += [os.path.join(python, f) for f in sorted(os.listdir(os.path.join(source_dir, python))) if f.endswith(".py")]
    wrong, seen = [], 0
    for relative in files:
        for line, names in written_lists(os.path.join(source_dir, relative), order):
            seen += 1
            if names != order:
                wrong.append(f"{relative}:{line}: {', '.join(names)} (the engine's order: {', '.join(order)})")
    for line in wrong:
        print(line)
    print(f"phone_set_order_test: {seen} written lists checked against {', '.join(order)}")
    return 1 if wrong or seen < 3 else 0


if __name__ == "__main__":
    sys.exit(main())
