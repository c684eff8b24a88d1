#!/usr/bin/env bash
# shapesim-calibrate --help and a bad option (checks in ../lib.sh).
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
check_help shapesim-calibrate
