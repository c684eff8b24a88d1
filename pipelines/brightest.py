#!/usr/bin/env python3
"""Print "FILE ID" of the brightest record (smallest "mag") over JSON-lines files:
   pipelines/brightest.py sources.jsonl [more.jsonl ...]"""
import json
import sys

best = None
for path in sys.argv[1:]:
    with open(path) as f:
        for line in f:
            r = json.loads(line)
            if r.get("mag") is not None and (best is None or r["mag"] < best[0]):
                best = (r["mag"], path, r["id"])
if best is None:
    sys.exit("brightest.py: no record with a magnitude in " + " ".join(sys.argv[1:]))
print(best[1], best[2])
