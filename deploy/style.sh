#!/usr/bin/env bash
# The style checks CI runs (docs/architecture.md, "Style and checks"):
#   1. clang-format-14 in check mode over every C++ file git tracks: the layout of the top-level
#      .clang-format (Google, 120 columns). Fix with: clang-format-14 -i FILE...
#   2. clang-tidy-14 (.clang-tidy: bugprone, performance, naming) over every source file of the
#      programs and libraries, with the headers they include; generated code and tests are not
#      checked. It needs build/compile_commands.json (deploy/build.sh writes it).
#   3. names reserved to the implementation (C++ [lex.name]: a double underscore anywhere, or an
#      underscore and a capital first) appear in the sources only where the compiler, its
#      sanitizers or the C library provide them (the list below). clang-tidy's
#      bugprone-reserved-identifier checked this at a fifth of the lint's time (15-35 % of a unit's,
#      measured on four): it writes a finding for each of the thousands of such names in a unit's
#      system headers, and only then throws them away.
# Usage: deploy/style.sh [format|tidy|names] (all three when not given). Exits non-zero on any finding.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
what="${1:-all}"
status=0

if [[ "$what" == all || "$what" == format ]]; then
  mapfile -t sources < <(git ls-files '*.cpp' '*.hpp' '*.h' '*.cc')
  if ! clang-format-14 --dry-run -Werror "${sources[@]}"; then
    echo "style: the files above are not laid out as .clang-format says (clang-format-14 -i FILE...)" >&2
    status=1
  else
    echo "style: clang-format: ${#sources[@]} files laid out as .clang-format says"
  fi
fi

if [[ "$what" == all || "$what" == names ]]; then
  provided='__attribute__|__has_feature|__restrict|__builtin_[a-z_]+|__m(128|256)[di]?'
  provided+='|__(SSE2|x86_64|GNUC|clang|SANITIZE_ADDRESS|SANITIZE_THREAD)__|__(tsan|lsan)_[a-z_]+|_Exit|_SC_[A-Z_]+'
  provided+='|_Z[A-Za-z0-9_]+'  # mangled names, in strings: the TSan build's interposed symbols
  reserved=$(git grep -noE '\b(_[A-Z_][A-Za-z0-9_]*|[A-Za-z0-9_]*[A-Za-z0-9]__[A-Za-z0-9_]*)' -- \
               '*.cpp' '*.hpp' '*.h' '*.cc' | grep -vE ":($provided)\$" || true)
  if [[ -n "$reserved" ]]; then
    echo "$reserved" >&2
    echo "style: the names above are reserved to the implementation (a double underscore, or an underscore and" \
      "a capital first): name your own otherwise, or add one the compiler provides to the list in deploy/style.sh" >&2
    status=1
  else
    echo "style: names: none reserved to the implementation but those it provides"
  fi
fi

if [[ "$what" == all || "$what" == tidy ]]; then
  if [[ ! -f build/compile_commands.json ]]; then
    echo "style: build/compile_commands.json is missing: run deploy/build.sh first" >&2
    exit 2
  fi
  mapfile -t units < <(/usr/bin/python3 - <<'PY'
import json, os
root = os.getcwd() + "/"
for entry in json.load(open("build/compile_commands.json")):
    path = entry["file"]
    if path.startswith(root) and not path.startswith((root + "build", root + "tests/")):
        print(path)
PY
)
  start=$SECONDS
  log="$(mktemp)"
  # One unit per process, two at a time; --quiet keeps only the findings.
  if ! printf '%s\n' "${units[@]}" | xargs -P "$(nproc)" -n 1 clang-tidy-14 -p build --quiet --warnings-as-errors='*' >"$log" 2>&1; then
    grep -E "(warning|error):" "$log" | sort -u >&2 || cat "$log" >&2
    echo "style: clang-tidy found the above in ${#units[@]} units ($((SECONDS - start)) s)" >&2
    status=1
  else
    echo "style: clang-tidy: ${#units[@]} units clean ($((SECONDS - start)) s)"
  fi
  rm -f "$log"
fi
exit $status
