#!/usr/bin/env bash
# shapesim-decompose --version (checks in ../lib.sh).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
check_version shapesim-decompose
