#!/usr/bin/env bash
# make install into a staging root (DESTDIR, PREFIX=/usr), then used from another directory:
# every installed program answers --version, every man page names its program, every shipped
# survey runs by name from the prefix alone, no app/ header
# is installed, and a program compiled with `pkg-config --cflags --libs shapesim` alone renders
# a shapelet model whose summed pixels equal the closed form 2√π β (a_00 + a_20) to 1e-6.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
root=$(cd ../../.. && pwd)
command -v help2man >/dev/null || { echo "no help2man (share/scripts/install-deps.sh)"; exit 77; }
command -v pkg-config >/dev/null || { echo "no pkg-config"; exit 77; }

# The build under test: the programs of $BIN (SAN=1 builds into build-san/bin), nothing rebuilt.
# The outer make's flags and jobserver are not this make's.
san=$([ "$BIN" = "$root/build-san/bin" ] && echo SAN=1 || true)
stage=$TMPDIR/root
env -u MAKEFLAGS -u MAKELEVEL -u MFLAGS make -C "$root" --no-print-directory $san install \
  DESTDIR="$stage" PREFIX=/usr >"$TMPDIR/install.log" 2>&1 ||
  { tail -n 20 "$TMPDIR/install.log"; fail "make install failed"; }
usr=$stage/usr

mkdir "$TMPDIR/elsewhere" && cd "$TMPDIR/elsewhere"
programs=(detect decompose smooth sample lens render measure calibrate survey table)
for p in "${programs[@]}"; do
  prog=shapesim-$p
  BIN=$usr/bin check_version "$prog"
  page=$usr/share/man/man1/$prog.1
  [ -s "$page" ] || fail "no man page $page"
  th=$(grep -m 1 -v '^\.\\"' "$page")  # the first line after the comments
  grep -qi "^\.TH \"\?$prog\"\? \"\?1\"\? " <<<"$th" || fail "$page does not start with .TH $prog 1: $th"
  grep -q "^$prog \\\\- [a-z]" "$page" || fail "$page: no NAME line '$prog \\- …'"
  if command -v man >/dev/null; then
    text=$(MANWIDTH=80 man -l "$page" 2>&1) && grep -q '^SYNOPSIS' <<<"$text" ||
      fail "man -l $page: no SYNOPSIS"
  fi
done
[ "$(ls "$usr/bin")" = "$(printf 'shapesim-%s\n' "${programs[@]}" | sort)" ] ||
  fail "installed programs: $(ls "$usr/bin")"

# Every shipped survey, by name, from the prefix alone (its models, its programs): an image and
# its truth in one command (a small corner of each field).
for survey in "$usr"/share/shapesim/surveys/*.survey; do
  name=$(basename "$survey" .survey)
  # 400 pixels a side: at ACS's 0.03″ (0.04 arcmin²) the count law puts 8 galaxies there.
  "$usr/bin/shapesim-survey" "$name" --pixels 400 -q -o "sim-$name" ||
    fail "shapesim-survey $name failed from the installed prefix"
  [ -s "sim-$name/image.fits" ] && [ -s "sim-$name/truth.jsonl" ] && [ -s "sim-$name/truth.fits" ] &&
    [ -s "sim-$name/commands.sh" ] ||
    fail "shapesim-survey $name: missing outputs"
  grep -q "$usr/share/shapesim/models/" "sim-$name/commands.sh" || fail "$name: not the installed model"
done
[ "$(ls "$usr"/share/shapesim/surveys/*.survey | wc -l)" -ge 3 ] || fail "fewer than 3 shipped surveys"

# The public headers, without app/ (program plumbing), and none of them reaching into it; the
# library without program code: no app/ or program object, nothing of Boost.ProgramOptions.
[ -s "$usr/include/shapesim/render.hpp" ] && [ -s "$usr/lib/libshapesim.a" ] || fail "no library"
[ ! -e "$usr/include/shapesim/app" ] || fail "app/ headers installed"
! grep -lE '#include "(app|detect|decompose|smooth|sample|render|measure|lens|calibrate|survey|table)/' \
  "$usr"/include/shapesim/*.hpp || fail "a public header includes program code"
members=$(ar t "$usr/lib/libshapesim.a")
! grep -xE '(options|run_main|detection_run|field_options|provenance|gnuplot|compare_run|settings|source_fields|main)\.o' \
  <<<"$members" || fail "program code in libshapesim.a: $(tr '\n' ' ' <<<"$members")"
! nm -C "$usr/lib/libshapesim.a" 2>/dev/null | grep -q 'boost::program_options' ||
  fail "libshapesim.a uses Boost.ProgramOptions"

# The library through pkg-config only. --define-prefix: prefix from where shapesim.pc lies.
export PKG_CONFIG_PATH=$usr/lib/pkgconfig
pc=(pkg-config --define-prefix shapesim)
for v in includedir:include libdir:lib; do
  got=$("${pc[@]}" --variable="${v%%:*}")
  [ "$got" = "$usr/${v#*:}" ] || fail "shapesim.pc ${v%%:*}: $got"
done
cat >flux.cpp <<'EOF'
#include "shapesim/model.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/render.hpp"
#include "shapesim/version.hpp"

#include <cstdio>

int main() {
    shapesim::ShapeletModel model(32.0, 31.5, 2.5, 2);  // centre (32, 31.5), β 2.5 px
    model.at(0, 0) = 3.0;
    model.at(2, 0) = 0.5;
    model.at(2, 2) = {0.25, -0.1};  // carries no flux
    const shapesim::ImageArray stamp = shapesim::render_stamp(model, 64, 64);
    std::printf("%s %.17g %.17g\n", shapesim::version(), stamp.sum(), shapesim::flux(model));
}
EOF
# shellcheck disable=SC2046
${CXX:-g++} -std=c++17 -O2 flux.cpp $("${pc[@]}" --cflags --libs) -o flux ||
  fail "compile/link with: $("${pc[@]}" --cflags --libs)"
read -r version sum flux < <(./flux)
[ "$version" = "$("${pc[@]}" --modversion)" ] ||
  fail "library version $version, shapesim.pc $("${pc[@]}" --modversion)"
awk -v s="$sum" -v f="$flux" 'BEGIN {
  exact = 2 * sqrt(atan2(0, -1)) * 2.5 * (3.0 + 0.5)
  ds = (s - exact) / exact; df = (f - exact) / exact
  if (ds < 0) ds = -ds; if (df < 0) df = -df
  if (ds > 1e-6 || df > 1e-6) { printf "sum %.12g flux() %.12g, closed form %.12g\n", s, f, exact; exit 1 }
}' || fail "rendered flux off the closed form"
