#!/usr/bin/env python3
"""Odd JSON inputs for the corpus matrix (tests/corpus/matrix.sh), derived from a valid input.

    mutate.py KIND < valid > odd

KIND is one of the names in MUTATIONS. Record-wise kinds change the first record of a
JSON-lines file (or the one JSON document), so every program meets a value it must refuse or
survive in the place it reads it: every number replaced by 0, by its negative, by 1e308, by
null or by a string; the schema renamed; the last line cut in half; a huge n_max-like
integer. Stdlib only (the bare python3)."""
import json
import sys


def numbers(value, change):
    """`value` with every number (not bool) passed through `change`, recursively."""
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return change(value)
    if isinstance(value, list):
        return [numbers(v, change) for v in value]
    if isinstance(value, dict):
        return {k: numbers(v, change) for k, v in value.items()}
    return value


def integers(value, change):
    """`value` with every integer (not bool) passed through `change`, recursively."""
    if isinstance(value, bool) or not isinstance(value, (int, list, dict)):
        return value
    if isinstance(value, int):
        return change(value)
    if isinstance(value, list):
        return [integers(v, change) for v in value]
    return {k: integers(v, change) for k, v in value.items()}


def rename_schema(record):
    if isinstance(record, dict) and "schema" in record:
        record = dict(record, schema="shapesim.nothing/1")
    return record


MUTATIONS = {
    "zeros": lambda r: numbers(r, lambda v: 0),
    "negative": lambda r: numbers(r, lambda v: -v if v else -1),
    "huge": lambda r: numbers(r, lambda v: 1e308),
    "nulls": lambda r: numbers(r, lambda v: None),
    "strings": lambda r: numbers(r, lambda v: str(v)),
    "big-integers": lambda r: integers(r, lambda v: 2**40 + 7),
    "wrong-schema": rename_schema,
}


def main():
    kind = sys.argv[1]
    text = sys.stdin.read()
    if kind == "truncated":
        cut = text.rstrip("\n")
        sys.stdout.write(cut[: len(cut) - max(1, len(cut.splitlines()[-1]) // 2)])
        return
    change = MUTATIONS[kind]
    try:  # one JSON document (a morphology model) ...
        document = json.loads(text)
        sys.stdout.write(json.dumps(change(document)) + "\n")
        return
    except json.JSONDecodeError:
        pass
    lines = text.splitlines()  # ... or JSON lines: change the first record
    lines[0] = json.dumps(change(json.loads(lines[0])))
    sys.stdout.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
