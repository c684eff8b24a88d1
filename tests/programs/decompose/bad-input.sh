#!/usr/bin/env bash
# shapesim-decompose on bad input.
#  - Input errors (wrong schema, malformed JSON, missing stamps file or stamp HDU, no
#    stamp_file without --stamps): exit 1, one stderr line "shapesim-decompose: …" naming
#    the place, nothing on stdout and no --models file (nor a temporary) left behind.
#  - Usage errors (--ids without --models, an option out of range): exit 2, "(see --help)".
#  - A stamp no fit can use (start centre outside it; and, with python3 to edit the FITS
#    file, all pixels masked, all weights 0, all pixels NaN): one warning line naming the
#    object, the object skipped, the others written, exit 0.
source "$(dirname "${BASH_SOURCE[0]}")/../lib.sh"
prog=shapesim-decompose

cd "$TMPDIR"
hdf_sources
mv sources.jsonl all.jsonl
head -n 4 all.jsonl >four.jsonl
[ "$(wc -l <four.jsonl)" -eq 4 ] || fail "fewer than 4 sources from shapesim-detect"
# The records name stamps.fits relative to here; a good run first.
"$BIN/$prog" -q <four.jsonl >good.jsonl || fail "the good input fails"
[ "$(wc -l <good.jsonl)" -eq 4 ] || fail "good input: $(wc -l <good.jsonl) records, expected 4"

# id LINE: the id of line LINE of four.jsonl.
id() {
  sed -n "$1p" four.jsonl | grep -o '^{"schema":"[^"]*","id":"[^"]*"' | sed 's/.*"id":"//; s/"$//'
}

# run_error WANT REGEX INPUT [OPTION]...: the program reads INPUT on stdin with --models and
# OPTIONs, exits WANT with one stderr line matching REGEX, writes nothing on stdout and leaves
# no models file.
run_error() {
  local want=$1 regex=$2 input=$3 rc=0
  shift 3
  "$BIN/$prog" --models models.fits "$@" <"$input" >out 2>err || rc=$?
  expect_error "$rc" "$want" "$regex"
  [ ! -s out ] || fail "stdout not empty: $(head -c 200 out)"
  [ -z "$(ls -A | grep '^models')" ] || fail "left behind: $(ls -A | grep '^models' | tr '\n' ' ')"
}

# A shapesim.shapelet/1 line where a source is expected (a second run's mistake).
sed '1s/"schema":"shapesim.source\/1"/"schema":"shapesim.shapelet\/1"/' four.jsonl >wrong.jsonl
run_error 1 '^shapesim-decompose: -:1: .*shapesim\.source/1' wrong.jsonl
# Malformed JSON on line 3, from a named file and from stdin: the error names file and line.
{ head -n 2 four.jsonl; echo '{"schema":"shapesim.source/1","id":'; } >bad.jsonl
run_error 1 '^shapesim-decompose: bad\.jsonl:3: .*JSON' /dev/null -i bad.jsonl
{ head -n 2 four.jsonl; echo 'not json'; } >bad2.jsonl
run_error 1 '^shapesim-decompose: -:3: .*JSON' bad2.jsonl
# The stamps file is missing.
run_error 1 '^shapesim-decompose: nosuch\.fits: ' four.jsonl --stamps nosuch.fits
# A record whose stamp HDU is not in the file.
sed '2s/"stamp_hdu":"[^"]*"/"stamp_hdu":"nosuch"/' four.jsonl >nohdu.jsonl
grep -q '"stamp_hdu":"nosuch"' nohdu.jsonl || fail "no stamp_hdu in the records"
run_error 1 "^shapesim-decompose: .*nosuch" nohdu.jsonl
# A record without stamp_file, and no --stamps.
sed '3s/"stamp_file":"[^"]*",//' four.jsonl >nofile.jsonl
run_error 1 '^shapesim-decompose: -:3: .*stamp_file' nofile.jsonl
# A record field of the wrong type.
sed '2s/"noise_correlation":[^,]*,/"noise_correlation":"high",/' four.jsonl >type.jsonl
run_error 1 '^shapesim-decompose: -:2: noise_correlation: ' type.jsonl

# Usage errors.
rc=0
"$BIN/$prog" --ids 1,2 <four.jsonl >out 2>err || rc=$?
expect_error "$rc" 2 '^shapesim-decompose: .*--ids.*(see --help)$'
[ ! -s out ] || fail "--ids without --models wrote to stdout"
run_error 2 '^shapesim-decompose: .*--beta-tolerance.*(see --help)$' four.jsonl --beta-tolerance 2
run_error 2 '^shapesim-decompose: .*--n-max-cap.*(see --help)$' four.jsonl --n-max-cap 101
run_error 2 '^shapesim-decompose: --band-noise-model takes NAME=FILE.*(see --help)$' four.jsonl \
  --band-noise-model f814w
run_error 2 '^shapesim-decompose: --white-noise and a noise model exclude.*(see --help)$' \
  four.jsonl --white-noise --noise-model noise.jsonl
# A measured correlation (the sky's noise record) runs: the same objects, each its exact
# noise take-up; a missing record is an input error.
"$BIN/shapesim-detect" -q "$HDF_IMAGE" --weight "$HDF_DATA/hdfn_f814w_v2_weight.fits" \
  --noise-model noise.jsonl >/dev/null || fail "shapesim-detect --noise-model failed"
"$BIN/$prog" -q --noise-model noise.jsonl <four.jsonl >exact.jsonl || fail "--noise-model fails"
[ "$(wc -l <exact.jsonl)" -eq 4 ] || fail "--noise-model: $(wc -l <exact.jsonl) records, expected 4"
run_error 1 '^shapesim-decompose: nosuch\.jsonl: cannot open' four.jsonl --noise-model nosuch.jsonl
# An unwritable --models path fails before any work.
rc=0
"$BIN/$prog" --models nosuch/models.fits <four.jsonl >out 2>err || rc=$?
expect_error "$rc" 1 '^shapesim-decompose: nosuch/models\.fits: '
[ ! -s out ] || fail "unwritable --models: wrote to stdout"
# A missing --stamps or --psf file is an error even on empty input (issue 15).
rc=0; "$BIN/$prog" --stamps nosuch.fits </dev/null >out 2>err || rc=$?
expect_error "$rc" 1 '^shapesim-decompose: nosuch\.fits: cannot open'
rc=0; "$BIN/$prog" --psf nosuch.jsonl </dev/null >out 2>err || rc=$?
expect_error "$rc" 1 '^shapesim-decompose: nosuch\.jsonl: cannot open'

# expect_skipped INPUT STAMPS LINE: the object on LINE is skipped with one warning naming it;
# the other three are written as in the good run; exit 0; the models file has their images.
expect_skipped() {
  local input=$1 stamps=$2 line=$3 rc=0 bad
  bad=$(id "$line")
  "$BIN/$prog" --stamps "$stamps" --models models.fits <"$input" >out 2>err || rc=$?
  [ "$rc" -eq 0 ] || fail "$input/$stamps: exit $rc: $(cat err)"
  [ "$(grep -c warning err)" -eq 1 ] || fail "$input/$stamps: expected one warning: $(cat err)"
  grep -q "^shapesim-decompose: warning: object $bad " err ||
    fail "$input/$stamps: the warning does not name object $bad: $(cat err)"
  sed "${line}d" good.jsonl >want
  cmp -s want out || fail "$input/$stamps: the other records differ from the good run's"
  [ "$(LC_ALL=C grep -a -c "EXTNAME = '$bad\.data" models.fits)" -eq 0 ] ||
    fail "$input/$stamps: images of the skipped object $bad in --models"
  [ "$(LC_ALL=C grep -a -o "EXTNAME = '[^']*'" models.fits | wc -l)" -eq 9 ] ||
    fail "$input/$stamps: --models does not hold the other three objects' images"
  rm -f models.fits
}

# A centre far outside its stamp.
sed '2s/"x":[^,]*,"y":[^,]*,/"x":-5000.5,"y":99999.5,/' four.jsonl >outside.jsonl
grep -q '"x":-5000.5' outside.jsonl || fail "could not move the centre"
expect_skipped outside.jsonl stamps.fits 2

# Stamps no fit can use, made by overwriting one plane of object 3's stamp.
command -v python3 >/dev/null || exit 0
# fill FITS EXTNAME BYTE: set every data byte of HDU EXTNAME to BYTE.
fill() {
  python3 - "$@" <<'PY'
import sys
path, extname, byte = sys.argv[1], sys.argv[2], int(sys.argv[3])
data = bytearray(open(path, "rb").read())
pos = 0
while pos < len(data):
    cards, p = {}, pos
    while True:
        card = data[p:p + 80].decode("ascii")
        p += 80
        if card[:8].strip() == "END":
            break
        if card[8:10] == "= ":
            cards[card[:8].strip()] = card[10:].split("/")[0].strip().strip("'").strip()
    start = (p + 2879) // 2880 * 2880
    naxis = int(cards.get("NAXIS", 0))
    size = abs(int(cards["BITPIX"])) // 8 if naxis else 0
    for k in range(1, naxis + 1):
        size *= int(cards["NAXIS%d" % k])
    if cards.get("EXTNAME") == extname:
        data[start:start + size] = bytes([byte]) * size
        open(path, "wb").write(data)
        sys.exit(0)
    pos = start + (size + 2879) // 2880 * 2880
sys.exit("no HDU " + extname)
PY
}
third=$(id 3)
for plane in mask:1 weight:0 image:255; do  # mask 1 everywhere; weight 0.0; image NaN
  cp stamps.fits edited.fits
  fill edited.fits "$third.${plane%:*}" "${plane#*:}" || fail "could not edit $third.${plane%:*}"
  cmp -s stamps.fits edited.fits && fail "editing $third.${plane%:*} changed nothing"
  expect_skipped four.jsonl edited.fits 3
done
