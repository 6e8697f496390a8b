#!/usr/bin/env python3
"""How many pixels `--basis auto`'s choice needs: its stability against the pixels spent.

`auto` chooses by successive halving (`relit::fit::Halving`): every candidate under
every variant (space and objective) is screened on a few pixels and half the folds, and
the best few go on to the full validation on more pixels. For every
../shared/data/realrti item this runs the peer protocol (`relit eval ITEM --json`: five
fits, each choosing on its own training lights) once per setting of the hidden flags
`--screening-pixels`, `--finalists`, `--selection-pixels` and `--subsample`, and
compares each of the 5 × items choices with the reference setting's (every candidate
validated in full on 1024 pixels, no screening): the same basis, λ and space, and the
held-out 8-bit sRGB PSNR that results. Fit seconds are the mean of the hold-out fits
(2 cores: compare settings within one run). Usage:
    scripts/choice_stability.py [RELIT_BINARY] [--keep DIR] [--items item1,item2]
"""
import argparse, json, pathlib, subprocess, statistics

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("relit", nargs="?", default=str(root / "target/release/relit"))
ap.add_argument("--keep", help="folder for the raw JSON (reused when present)")
ap.add_argument("--items", help="comma-separated items (default all)")
ap.add_argument("--settings", help="comma-separated setting names (default all)")
args = ap.parse_args()
data = root.parent / "shared/data/realrti"
keep = pathlib.Path(args.keep) if args.keep else None
if keep:
    keep.mkdir(parents=True, exist_ok=True)

# name: (screening pixels, finalists, selection pixels, subsample)
SETTINGS = {
    "reference (all in full, 1024 px)": (1024, 6, 1024, 1024),
    "screen 256 → 6 on 512": (256, 6, 512, 1024),
    "screen 128 → 6 on 512 (default until 2026-12-07)": (128, 6, 512, 1024),
    "screen 64 → 6 on 512": (64, 6, 512, 1024),
    "screen 32 → 6 on 512": (32, 6, 512, 1024),
    "screen 64 → 4 on 512": (64, 4, 512, 1024),
    "screen 64 → 8 on 512": (64, 8, 512, 1024),
    "screen 128 → 6 on 256": (128, 6, 256, 1024),
    "screen 64 → 6 on 256": (64, 6, 256, 1024),
    "screen 64 → 6 on 1024": (64, 6, 1024, 1024),
    "screen 64 → 4 on 1024 (default)": (64, 4, 1024, 1024),
    "screen 64 → 3 on 1024": (64, 3, 1024, 1024),
    "screen 64 → 2 on 512": (64, 2, 512, 1024),
    "screen 64 → 2 on 1024": (64, 2, 1024, 1024),
}
names = list(SETTINGS)
if args.settings:
    wanted = args.settings.split(",")
    names = [n for n in names if any(w in n for w in wanted)] or names
    if names[0] != list(SETTINGS)[0]:
        names.insert(0, list(SETTINGS)[0])


def evaluate(item, name):
    s, f, p, sub = SETTINGS[name]
    tag = f"{item}_s{s}_f{f}_p{p}_n{sub}"
    cached = keep / f"{tag}.json" if keep else None
    if cached and cached.exists():
        return json.loads(cached.read_text())
    cmd = [args.relit, "eval", str(data / item / "dirs.lp"), "--json", "-q",
           "--screening-pixels", str(s), "--finalists", str(f),
           "--selection-pixels", str(p), "--subsample", str(sub)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    if cached:
        cached.write_text(out)
    return json.loads(out)


def choices(run):
    """Each hold-out fit's choice: basis, λ and the maps' space."""
    return [(h["basis"], h["lambda"], h["candidates"][0].get("space")) for h in run["holdouts"]]


items = args.items.split(",") if args.items else sorted(p.name for p in data.glob("item*"))
items.sort(key=lambda s: int(s[4:]))
runs = {n: {i: evaluate(i, n) for i in items} for n in names}
ref = runs[names[0]]
print(f"{len(items)} items × 5 hold-out fits = {5 * len(items)} choices per setting\n")
print("| setting | choices as the reference's | held-out dB, mean | Δ reference per item (min … max) | fit s per hold-out |")
print("|---|---:|---:|---|---:|")
for n in names:
    same = sum(a == b for i in items for a, b in zip(choices(runs[n][i]), choices(ref[i])))
    mean = statistics.mean(runs[n][i]["psnr_srgb8_mean"] for i in items)
    deltas = [runs[n][i]["psnr_srgb8_mean"] - ref[i]["psnr_srgb8_mean"] for i in items]
    seconds = statistics.mean(h["fit_seconds"] for i in items for h in runs[n][i]["holdouts"])
    print(f"| {n} | {same}/{5 * len(items)} | {mean:.3f} | {min(deltas):+.3f} … {max(deltas):+.3f} "
          f"| {seconds:.3f} |", flush=True)
print("\nPer item, held-out dB (first row the reference):")
print("| setting | " + " | ".join(items) + " |")
print("|---|" + "---:|" * len(items))
for n in names:
    print(f"| {n} | " + " | ".join(f"{runs[n][i]['psnr_srgb8_mean']:.2f}" for i in items) + " |")
