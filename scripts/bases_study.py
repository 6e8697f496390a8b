#!/usr/bin/env python3
"""Seed 002 reproduced: spherical Gaussian kernels (SG) against spherical harmonics (SH)
at equal size on a dense capture of the attic, and what `--basis auto` makes of it.

Runs, with the release binary (default target/release/relit):
  1. `relit capture attic --lights fibonacci:3072 --size 512x128` (as seed 002's 3072
     lights, at a quarter of the demo's panorama);
  2. `relit eval CAPTURE --holdout H --joint --basis B --json --save DIR` for every basis B
     (sh/sg at 16, 25, 36, 64; auto up to 25 and up to 64; any extra given with --extra),
     H = 24 captured lights of the upper hemisphere (y > 0.1), evenly spread;
  3. `relit bench --basis B --case point` at the capture's size for the relight speed.
Prints a Markdown table (held-out PSNR linear and 8-bit sRGB, bytes per pixel of the
half-float EXR, fit seconds, point-light frames per second), writes `--json FILE` with
every raw result and, with `--pictures DIR`, one held-out light's truth and relit
images per basis (PNG). Usage:
    scripts/bases_study.py [--relit BIN] [--json FILE] [--pictures DIR] [--keep DIR]
                           [--sizes 16,25,36,64] [--extra "rbf:64 bilinear:64"] [--no-auto]
"""
import argparse, json, pathlib, shutil, subprocess, sys, tempfile, time

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("--relit", default=str(root / "target/release/relit"))
ap.add_argument("--json")
ap.add_argument("--pictures")
ap.add_argument("--keep", help="keep (or reuse) the capture in this folder")
ap.add_argument("--sizes", default="16,25,36,64")
ap.add_argument("--extra", default="")
ap.add_argument("--objective", default="auto")
ap.add_argument("--no-auto", action="store_true", help="skip the two `auto` rows")
opts = ap.parse_args()


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def run(*args):
    t = time.time()
    out = subprocess.run([opts.relit, *map(str, args)], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"relit {' '.join(map(str, args))} failed:\n{out.stderr}")
    return out.stdout, time.time() - t


tmp = tempfile.TemporaryDirectory()
cap = pathlib.Path(opts.keep) if opts.keep else pathlib.Path(tmp.name) / "attic3072"
if not (cap / "capture.json").exists():
    log("capture: attic, 3072 Fibonacci lights, 512x128")
    run("capture", "attic", "--lights", "fibonacci:3072", "--size", "512x128", "--out", cap, "-q")
manifest = json.loads((cap / "capture.json").read_text())
upper = [i for i, im in enumerate(manifest["images"]) if im["direction"][1] > 0.1]
held = [upper[round(i * (len(upper) - 1) / 23)] for i in range(24)]

sizes = [int(k) for k in opts.sizes.split(",") if k]
bases = [f"{fam}:{k}" for k in sizes for fam in ("sh", "sg")]
if not opts.no_auto:
    bases += [("auto", 25), ("auto", 64)]
bases += opts.extra.split()  # space-separated: a basis may carry options with commas
results = {}
print("| basis | chosen | held-out linear dB | held-out sRGB8 dB | bytes/px | fit s | point fps |")
print("|---|---|---|---|---|---|---|")
for b in bases:
    if isinstance(b, tuple):
        name, flags = f"auto≤{b[1]}", ["--basis", "auto", "--max-coefficients", str(b[1])]
    else:
        name, flags = b, ["--basis", b]
    log(f"eval: {name}")
    save = pathlib.Path(tmp.name) / f"save-{len(results)}"
    out, wall = run("eval", cap / "capture.json", "--holdout", ",".join(map(str, held)), "--joint",
                    "--objective", opts.objective, *flags, "--save", save, "--json", "-q")
    r = json.loads(out)
    chosen = r["basis"]
    try:
        out, _ = run("bench", "--basis", chosen if ":" in chosen else b, "--case", "point",
                     "--size", "512x128", "--cpu-storage", "f16", "--no-gpu", "--quick", "--json")
        bench = json.loads(out)
    except SystemExit as e:  # a failed bench leaves the row without a speed, not the study
        log(str(e))
        bench = []
    rows = bench if isinstance(bench, list) else bench.get("rows", [])
    fps = next((row.get("fps") for row in rows if "point" in str(row.get("case", ""))), float("nan"))
    results[name] = {"eval": r, "bench": bench, "wall_seconds": wall}
    if opts.json:  # after every row: a long study stopped midway keeps what it measured
        pathlib.Path(opts.json).write_text(json.dumps(results, indent=1))
    print(f"| {name} | {chosen} | {r['psnr_linear_mean']:.2f} | {r['psnr_srgb8_mean']:.2f} "
          f"| {r['bytes_per_pixel']:.1f} | {r['fit_seconds']:.1f} | {fps:.0f} |", flush=True)
    if opts.pictures:
        dest = pathlib.Path(opts.pictures)
        dest.mkdir(parents=True, exist_ok=True)
        first = sorted(save.glob(f"{held[len(held) // 2]}_*.png"))
        if first:
            shutil.copy(first[0], dest / f"{name.replace(':', '-').replace('≤', 'max')}.png")
if opts.json:
    pathlib.Path(opts.json).write_text(json.dumps(results, indent=1))
