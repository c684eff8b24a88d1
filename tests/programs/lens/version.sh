#!/usr/bin/env bash
# shapesim-lens --version (checks in ../lib.sh).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
check_version shapesim-lens
