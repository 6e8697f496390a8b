#!/usr/bin/env python3
"""Two relit releases' default fits on the same captures, alternating, and whether they
give the same results.

For each capture, runs `BEFORE fit CAPTURE -o X.exr --json` and `AFTER fit …` in turn,
RUNS times each, and prints the fastest wall and processor time (the process's user +
system time) of each, and `same` where both chose the same basis and gave every
candidate the same validation PSNR and λ and the same training residual (`DIFF`
otherwise), then also where the EXR files' pixel chunks are byte for byte equal
(`maps same`; the header holds the fit's seconds). Usage:
    scripts/fit_releases.py BEFORE AFTER [--runs 5] [CAPTURE ...]
Captures default to the eight shared RealRTI items.
"""
import argparse, json, pathlib, resource, struct, subprocess, tempfile, time

root = pathlib.Path(__file__).resolve().parent.parent
items = [1, 2, 3, 5, 6, 7, 9, 11]
ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("before")
ap.add_argument("after")
ap.add_argument("captures", nargs="*",
                default=[str(root.parent / f"shared/data/realrti/item{i}/dirs.lp") for i in items])
ap.add_argument("--runs", type=int, default=5)
args = ap.parse_intermixed_args()
work = pathlib.Path(tempfile.mkdtemp(prefix="fit_releases."))


def fit(binary, capture, out):
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.time()
    p = subprocess.run([binary, "fit", capture, "-o", str(out), "--json"],
                       capture_output=True, text=True, check=True)
    wall = time.time() - t
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return wall, cpu, json.loads(p.stdout)


def pixel_chunks(path):
    """An OpenEXR file's bytes from its first chunk on (after the header and offsets)."""
    a = path.read_bytes()
    i = 8
    while a[i] != 0:
        name_end = a.index(b"\0", i)
        type_end = a.index(b"\0", name_end + 1)
        size = struct.unpack("<i", a[type_end + 1:type_end + 5])[0]
        i = type_end + 5 + size
    first = struct.unpack("<Q", a[i + 1:i + 9])[0]
    return a[first:]


def results(report):
    return ([(c["basis"], c["space"], c["psnr"], c["lambda"]) for c in report["candidates"]],
            report["basis"], report["rmse_linear"])


print("| capture | basis | wall s before → after | processor s before → after | results | maps |")
print("|---|---|---:|---:|---|---|")
sums = [0.0, 0.0, 0.0, 0.0]
for capture in args.captures:
    best = {"before": [1e9, 1e9, None], "after": [1e9, 1e9, None]}
    for _ in range(args.runs):
        for which, binary in (("before", args.before), ("after", args.after)):
            wall, cpu, report = fit(binary, capture, work / f"{which}.exr")
            b = best[which]
            b[0], b[1], b[2] = min(b[0], wall), min(b[1], cpu), report
    (wb, cb, rb), (wa, ca, ra) = best["before"], best["after"]
    same = "same" if results(rb) == results(ra) else "DIFF"
    maps = "maps same" if pixel_chunks(work / "before.exr") == pixel_chunks(work / "after.exr") else "maps DIFF"
    name = pathlib.Path(capture).parent.name
    print(f"| {name} | {ra['basis']} | {wb:.2f} → {wa:.2f} | {cb:.2f} → {ca:.2f} | {same} | {maps} |", flush=True)
    for k, v in enumerate((wb, wa, cb, ca)):
        sums[k] += v
print(f"\nsum: wall {sums[0]:.2f} → {sums[1]:.2f} s (×{sums[1] / sums[0]:.3f}), "
      f"processor {sums[2]:.2f} → {sums[3]:.2f} s (×{sums[3] / sums[2]:.3f})")
