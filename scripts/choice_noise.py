#!/usr/bin/env python3
"""How much of `--basis auto`'s result on an RTI capture is the luck of the hold-outs.

For every ../shared/data/realrti item: `relit eval ITEM --json` (peer protocol, the
default `auto`), then, for every basis that reached `auto`'s final round in any of the
five fits, `relit eval ITEM --json --candidate B` (the same validation and λ choice,
that basis alone). Prints, per item, the held-out 8-bit sRGB PSNR of `auto` and of each
finalist, and how far apart the finalists are on the hold-outs while their validation
scores (on the capture's own training lights) are within a fraction of a dB. Usage:
    scripts/choice_noise.py [RELIT_BINARY] [--keep DIR] [ITEM ...]
"""
import argparse, json, pathlib, subprocess, statistics

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("relit", nargs="?", default=str(root / "target/release/relit"))
ap.add_argument("--keep", help="folder for the raw JSON (reused when present)")
ap.add_argument("items", nargs="*")
args = ap.parse_args()
data = root.parent / "shared/data/realrti"
keep = pathlib.Path(args.keep) if args.keep else None
if keep:
    keep.mkdir(parents=True, exist_ok=True)


def evaluate(lp, name, extra):
    cached = keep / f"{lp.parent.name}_{name.replace(':', '_')}.json" if keep else None
    if cached and cached.exists():
        return json.loads(cached.read_text())
    out = subprocess.run([args.relit, "eval", str(lp), "--json", "-q"] + extra,
                         capture_output=True, text=True, check=True).stdout
    if cached:
        cached.write_text(out)
    return json.loads(out)


items = args.items or sorted(p.name for p in data.glob("item*"))
items.sort(key=lambda s: int(s[4:]))
print("| item | auto dB | finalists: held-out dB (validation dB, first fit) | best − worst finalist | auto − best |")
print("|---|---|---|---|---|")
spreads = []
for item in items:
    lp = data / item / "dirs.lp"
    auto = evaluate(lp, "auto", [])
    finalists = sorted({c["basis"] for h in auto["holdouts"] for c in h["candidates"]
                        if c["pixels"] == max(x["pixels"] for x in h["candidates"])})
    validation = {c["basis"]: c["psnr"] for c in auto["holdouts"][0]["candidates"]}
    held = {b: evaluate(lp, b, ["--candidate", b])["psnr_srgb8_mean"] for b in finalists}
    order = sorted(held, key=held.get, reverse=True)
    cells = ", ".join(f"{b} {held[b]:.2f} ({validation.get(b, float('nan')):.2f})" for b in order)
    spread = held[order[0]] - held[order[-1]]
    spreads.append(spread)
    print(f"| {item} | {auto['psnr_srgb8_mean']:.2f} | {cells} | {spread:.2f} | "
          f"{auto['psnr_srgb8_mean'] - held[order[0]]:+.2f} |", flush=True)
print(f"\nspread of the finalists' held-out PSNR: median {statistics.median(spreads):.2f} dB, "
      f"from {min(spreads):.2f} to {max(spreads):.2f}")
