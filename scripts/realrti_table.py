#!/usr/bin/env python3
"""The fidelity table over every ../shared/data/realrti item, beside relight-cli's figures.

Runs `relit eval ITEM/dirs.lp --holdout spread:5 --json` (the peer protocol: hold-outs at
round(i*(N-1)/4), one fit per hold-out, 8-bit sRGB PSNR over the whole frame) with the
given extra flags and prints a Markdown table. Usage:
    scripts/realrti_table.py [RELIT_BINARY] [-- extra relit eval flags]
"""
import json, pathlib, re, subprocess, sys

root = pathlib.Path(__file__).resolve().parent.parent
args = sys.argv[1:]
relit = args.pop(0) if args and args[0] != "--" else str(root / "target/release/relit")
extra = args[1:] if args and args[0] == "--" else []
shared = root.parent / "shared"

# Peer figures: sRGB-fit PSNR per item and basis, from the baseline's table.
peer = {}
for line in (shared / "reference/peer_baseline.md").read_text().splitlines():
    m = re.match(r"\| (item\d+) \(.*?\) \| (\w+ \d+) \| ([\d.]+) \|", line)
    if m:
        peer.setdefault(m.group(1), {})[m.group(2)] = float(m.group(3))

print("| item | images | size | basis | maps | relit sRGB8 dB (a) | relit linear dB (b) | bytes/px | fit s (each) | peak MiB | peer PTM 18 | peer best (basis) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
gains = []
for lp in sorted((shared / "data/realrti").glob("item*/dirs.lp"), key=lambda p: int(p.parent.name[4:])):
    item = lp.parent.name
    out = subprocess.run([relit, "eval", str(lp), "--holdout", "spread:5", "--json", "-q"] + extra,
                         capture_output=True, text=True, check=True)
    r = json.loads(out.stdout)
    p = peer.get(item, {})
    best = max(p.items(), key=lambda kv: kv[1]) if p else ("-", float("nan"))
    gains.append(r["psnr_srgb8_mean"] - best[1])
    print(f"| {item} | {r['images']} | {r['width']}×{r['height']} | {r['basis']} | {r['color_space']} | {r['psnr_srgb8_mean']:.2f} | {r['psnr_linear_mean']:.2f} "
          f"| {r['bytes_per_pixel']:.1f} | {r['fit_seconds']:.2f} | {r['peak_rss_bytes'] / 2**20:.0f} "
          f"| {p.get('ptm 18', float('nan')):.2f} | {best[1]:.2f} ({best[0]}) |", flush=True)
print(f"\nmean gain over the peer's best basis per item: {sum(gains) / len(gains):+.2f} dB")
