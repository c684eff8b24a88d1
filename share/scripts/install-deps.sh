#!/usr/bin/env bash
# Install the Debian packages shapesim needs, only those missing.
# As root: runs apt-get. Otherwise: prints the exact apt line and fails if anything is missing.
# Usage: install-deps.sh [--check]   (--check: only report, never install)
set -euo pipefail

packages=(
  g++ make pkg-config
  libcfitsio-dev            # FITS I/O
  wcslib-dev                # world coordinates: every FITS projection, SIP and TPV
  libeigen3-dev             # linear algebra
  libboost-program-options-dev
  nlohmann-json3-dev        # JSON lines
  libsep-dev                # SExtractor algorithms (detection)
  librandom123-dev          # counter-based random streams
  libgtest-dev              # unit tests
  libbenchmark-dev          # make bench
  source-extractor          # SExtractor, the cross-check of shapesim-detect (tests, bench)
  psfex                     # PSFEx: the varying PSF model render --psf-field reads (tests)
  fitsverify                # HEASARC's FITS checker (the survey test checks every image with it)
  python3-astropy           # tests: the FITS tables, ECSV and WCS read back by astropy
  gnuplot-nox               # shapesim-measure --compare figures
  netpbm                    # make reproduce: the figures as PNG (pnmtopng, pnmscale)
  help2man                  # make install: man pages from --help and --version
  clang libclang-rt-14-dev  # make fuzz: libFuzzer harnesses
  ccache                    # .ci/run: a compiler cache shared by CI's clean clones
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'ok installed' || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

line="apt-get install -y --no-install-recommends ${missing[*]}"
if [ "${1:-}" = "--check" ] || [ "$(id -u)" -ne 0 ]; then
  echo "shapesim: missing Debian packages; run as root:" >&2
  echo "  apt-get update && $line" >&2
  exit 1
fi
echo "shapesim: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >&2
# shellcheck disable=SC2086
apt-get install -y -qq --no-install-recommends ${missing[*]} >&2
