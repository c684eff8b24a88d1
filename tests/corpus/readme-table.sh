#!/usr/bin/env bash
# Copy the case × program table of MATRIX (its lines up to the first blank one) into README
# between the lines `<!-- corpus-matrix begin -->` and `<!-- corpus-matrix end -->`.
#   readme-table.sh MATRIX README           rewrite README
#   readme-table.sh --check MATRIX README   exit 1 (with a diff) unless README is current
set -euo pipefail
check=0
[ "$1" = --check ] && { check=1; shift; }
matrix=$1 readme=$2
new=$(mktemp)
trap 'rm -f "$new"' EXIT
awk -v table="$(sed '/^$/q' "$matrix" | sed '/^$/d')" '
  /<!-- corpus-matrix begin -->/ { print; print table; skip = 1; found++; next }
  /<!-- corpus-matrix end -->/ { skip = 0 }
  !skip { print }
  END { if (found != 1) exit 3 }' "$readme" >"$new" ||
  { echo "readme-table.sh: $readme has no corpus-matrix markers" >&2; exit 1; }
if [ "$check" = 1 ]; then
  diff -u "$readme" "$new" >&2 || { echo "readme-table.sh: $readme's matrix is stale (make corpus-matrix)" >&2; exit 1; }
else
  cat "$new" >"$readme"
fi
