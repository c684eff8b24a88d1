#!/usr/bin/env bash
# shapesim-decompose --version: exit 0, one line on stdout:
# "shapesim-decompose (shapesim) <version>".
set -euo pipefail
prog=shapesim-decompose

out=$("$BIN/$prog" --version)
[ "$(wc -l <<<"$out")" -eq 1 ]
grep -q "^$prog (shapesim) ." <<<"$out"
