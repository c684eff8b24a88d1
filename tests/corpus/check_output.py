#!/usr/bin/env python3
"""Check a successful run's outputs for the corpus matrix and print what it made.

    check_output.py STDOUT [OUTPUT...]

STDOUT must be empty, one JSON document or JSON lines; each OUTPUT a whole FITS file (a
multiple of 2880 bytes starting with SIMPLE = T) or a directory (measure --compare's report,
which must hold table.md). Prints e.g. "5 records", "image", "report"; exits 1 naming what is
wrong. Stdlib only."""
import json
import os
import sys


def describe_stdout(path):
    with open(path, "rb") as f:
        text = f.read().decode("utf-8")
    if not text.strip():
        return []
    try:
        document = json.loads(text)
        if isinstance(document, dict) and "morphology" in str(document.get("schema")):
            return ["model"]
    except json.JSONDecodeError:
        pass
    lines = text.splitlines()
    for number, line in enumerate(lines, 1):
        try:
            json.loads(line)
        except json.JSONDecodeError as error:
            raise SystemExit(f"stdout line {number}: not JSON ({error})")
    return [f"{len(lines)} record{'s' if len(lines) != 1 else ''}"]


def describe_output(path):
    if os.path.isdir(path):
        if not os.path.isfile(os.path.join(path, "table.md")):
            raise SystemExit(f"{path}: no table.md")
        return "report"
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        head = f.read(30)
    if size == 0 or size % 2880 or not head.startswith(b"SIMPLE  =                    T"):
        raise SystemExit(f"{path}: not a whole FITS file ({size} bytes)")
    return "image" if path.endswith("sim.fits") else None


def main():
    made = describe_stdout(sys.argv[1])
    for path in sys.argv[2:]:
        what = describe_output(path)
        if what:
            made.append(what)
    print(", ".join(made) if made else "(empty)")


if __name__ == "__main__":
    main()
