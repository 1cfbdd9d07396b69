#!/usr/bin/python3
"""docs/architecture.md against the tree: the page names every folder a contributor looks for, and
every path it names below those folders exists.

The folders checked are
  - every folder one level below clients/, server/src/, tools/ and tests/, and
  - every deeper folder under those four that has a CMakeLists.txt of its own (a directory of the
    build, such as tests/integrations/blender/ or tests/install/consumer/).
Folders that hold no file at any depth, hidden folders and __pycache__ are left out: git keeps
neither empty folders nor caches, so they are not part of the tree a reader sees.

A folder counts as named when a code span of the page (text between backticks) is its path from
the repository root, with or without the final slash: `tools/perf/` or `tools/perf`. A code span
that is a path below one of the four folders (`tests/support/child_process.hpp`) must exist.

  architecture_test.py [SOURCE_DIR]      (default: the checkout this script is in)

Exit status 0 when the page and the tree agree; 1 with one line per folder the page does not name
and per path it names that does not exist.
"""
import os
import re
import sys

PAGE = os.path.join("docs", "architecture.md")
ROOTS = ("clients", "server/src", "tools", "tests")
SKIPPED = ("__pycache__",)


def holds_a_file(folder):
    """Whether `folder` holds a file at some depth."""
    return any(files for _, _, files in os.walk(folder))


def visible(name):
    return not name.startswith(".") and name not in SKIPPED


def checked_folders(source_dir):
    """The folders the page must name, as paths from `source_dir` with '/' between names."""
    folders = set()
    for root in ROOTS:
        top = os.path.join(source_dir, root)
        for name in sorted(os.listdir(top)):
            path = os.path.join(top, name)
            if visible(name) and os.path.isdir(path) and holds_a_file(path):
                folders.add(f"{root}/{name}")
        for parent, names, files in os.walk(top):
            names[:] = [name for name in names if visible(name)]
            depth = os.path.relpath(parent, top).count(os.sep) + 1
            if depth >= 2 and "CMakeLists.txt" in files:
                folders.add(os.path.relpath(parent, source_dir).replace(os.sep, "/"))
    return sorted(folders)


def code_spans(text):
    """The text of every inline code span of `text`, fenced blocks left out."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.findall(r"`([^`\n]+)`", text)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    source_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, os.pardir, os.pardir)
    with open(os.path.join(source_dir, PAGE), encoding="utf-8") as page:
        spans = code_spans(page.read())
    named = {span.rstrip("/") for span in spans}

    problems = []
    for folder in checked_folders(source_dir):
        if folder not in named:
            problems.append(f"{PAGE} does not name the folder {folder}/ "
                            f"(as `{folder}/`, in the row that says what it holds)")
    below_roots = re.compile(r"^(?:%s)/[\w.+/-]*$" % "|".join(re.escape(root) for root in ROOTS))
    for span in sorted(set(spans)):
        if below_roots.match(span) and not os.path.exists(os.path.join(source_dir, span)):
            problems.append(f"{PAGE} names {span}, which does not exist")

    for problem in problems:
        print(problem)
    if problems:
        return 1
    print(f"{PAGE} names all {len(checked_folders(source_dir))} folders of {', '.join(r + '/' for r in ROOTS)}, "
          "and every path it names below them exists")
    return 0


if __name__ == "__main__":
    sys.exit(main())
