#!/usr/bin/env python3
"""Minimal FITS reader for program tests (the bare python3 has no astropy/numpy).

    fitsdata.py FILE header          print the primary header cards, one per line
    fitsdata.py FILE sum             print NAXIS1 NAXIS2 and the sum of the pixels

As a module: read(path) -> (cards dict, nx, ny, pixels as a list of rows, bottom row first),
from the first HDU holding a 2-D image (or the one whose EXTNAME is `extname`); BITPIX -32,
-64, 8, 16, 32.
"""
import struct
import sys


def _header(data, pos, path):
    cards = {}
    while True:
        block = data[pos:pos + 2880]
        if len(block) < 2880:
            raise ValueError(f"{path}: truncated header")
        pos += 2880
        for k in range(36):
            card = block[80 * k:80 * (k + 1)].decode("ascii")
            key = card[:8].strip()
            if key == "END":
                return cards, pos
            if card[8:10] == "= ":
                text = card[10:].strip()
                cards[key] = text.split("'")[1].strip() if text.startswith("'") \
                    else text.split("/")[0].strip()


def read(path, extname=None):
    """The first HDU with a 2-D image (named `extname`, when given): (cards, nx, ny, rows
    bottom first)."""
    with open(path, "rb") as f:
        data = f.read()
    pos = 0
    while pos < len(data):
        cards, pos = _header(data, pos, path)
        bitpix, naxis = int(cards["BITPIX"]), int(cards.get("NAXIS", 0))
        size = abs(bitpix) // 8
        count = 1
        for k in range(1, naxis + 1):
            count *= int(cards[f"NAXIS{k}"])
        if naxis == 0:
            count = 0
        if naxis == 2 and (extname is None or cards.get("EXTNAME") == extname):
            nx, ny = int(cards["NAXIS1"]), int(cards["NAXIS2"])
            fmt = {-32: "f", -64: "d", 8: "B", 16: "h", 32: "i"}[bitpix]
            values = struct.unpack(f">{nx * ny}{fmt}", data[pos:pos + nx * ny * size])
            return cards, nx, ny, [values[j * nx:(j + 1) * nx] for j in range(ny)]
        pos += -(-count * size // 2880) * 2880
    raise ValueError(f"{path}: no 2-D image" + (f" named {extname}" if extname else ""))


if __name__ == "__main__":
    cards, nx, ny, rows = read(sys.argv[1])
    if sys.argv[2] == "header":
        for k, v in cards.items():
            print(f"{k}={v}")
    elif sys.argv[2] == "sum":
        print(nx, ny, sum(sum(r) for r in rows))
