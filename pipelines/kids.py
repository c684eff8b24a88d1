#!/usr/bin/env python3
"""Tables for pipelines/kids.sh (make kids), plain Python 3 (no third-party module).

kids.py INTRINSIC SOURCES STARS    the fits: converged share, the ten brightest galaxies
kids.py --bins REAL SIM            rms e and FWHM median per magnitude bin, real against sim
"""
import json
import math
import sys


def records(path):
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


def fits(intrinsic, sources, stars):
    models, detected, set_aside = records(intrinsic), records(sources), records(stars)
    n = len(models)
    converged = sum("converged" in m["flags"] for m in models)
    saturated = sum("saturated" in s.get("flags", []) for s in set_aside)
    print("## The fits")
    print()
    print(f"{len(detected)} galaxies detected ({len(set_aside)} stars set aside, "
          f"{saturated} of them saturated); {n} fitted through the PSF; "
          f"converged {converged} ({100.0 * converged / max(n, 1):.1f}%).")
    print()
    print("The ten brightest galaxies (a fit above χ²_r 1.5 carries the flags that say why):")
    print()
    print("| id | mag | n_max | χ²_r | stop | flags |")
    print("|---|---|---|---|---|---|")
    for m in sorted((m for m in models if "mag" in m), key=lambda m: m["mag"])[:10]:
        flags = ", ".join(f for f in m["flags"] if f not in ("converged", "not_converged"))
        print(f"| {m['id']} | {m['mag']:.2f} | {m['n_max']} | {m['chi2r']:.3f} | {m['stop']} | "
              f"{flags or '–'} |")
    print()
    print(f"converged_fraction {converged / max(n, 1):.4f}")


def bins(real_path, sim_path):
    edges = [(13, 21), (21, 22), (22, 23), (23, 24), (24, 26)]

    def galaxies(path):
        return [r for r in records(path)
                if r.get("kind") == "galaxy" and "mag" in r and "e1" in r and "fwhm" in r]

    cats = {"real": galaxies(real_path), "sim": galaxies(sim_path)}
    print("rms e and FWHM median (pixels) per magnitude bin (the δ seeds pooled):")
    print()
    print("| r | " + " | ".join(f"{a}–{b}" for a, b in edges) + " |")
    print("|---|" + "---|" * len(edges))
    for name, cat in cats.items():
        cells = []
        for a, b in edges:
            s = [r for r in cat if a <= r["mag"] < b]
            if not s:
                cells.append("–")
                continue
            rms = math.sqrt(sum(r["e1"] ** 2 + r["e2"] ** 2 for r in s) / len(s))
            fwhm = sorted(r["fwhm"] for r in s)[len(s) // 2]
            cells.append(f"{len(s)}: {rms:.3f} / {fwhm:.2f}")
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--bins":
        bins(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 4:
        fits(*sys.argv[1:])
    else:
        sys.exit(__doc__)
