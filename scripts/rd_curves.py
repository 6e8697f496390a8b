#!/usr/bin/env python3
"""Rate–distortion curves of the shared RTI items, and the tables of docs/rd.md.

Runs `relit eval ITEM/dirs.lp --rd --json` once per item (every point is a real file
written, read back and relit at the held-out lights; see `relit eval --help`), keeps
each report as OUT/ITEM.json (an item whose JSON exists is not run again unless
--force) and draws OUT/ITEM.svg from it (`relit eval --rd-report`), then prints per item
the Pareto front and the best point within --budget bits/px beside relight-cli's best
basis (shared/reference/peer_baseline.md), as Markdown.

    scripts/rd_curves.py target/release/relit [--items item1,item3] [--out docs/rd]
        [--budget 24] [--force] [-- extra relit eval flags, e.g. --rd-basis sh:25]
"""
import argparse, json, pathlib, re, subprocess, sys, time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def peer_best(baseline):
    """item -> (PSNR sRGB-fit, basis, bits/px) of the peer's best basis."""
    best = {}
    for line in baseline.read_text().splitlines():
        m = re.match(r"\| (item\d+) \(.*?\) \| (\w+ \d+) \| ([\d.]+) \|.*\| ([\d.]+) \| [\d.]+ \|$", line)
        if m:
            item, basis, psnr, bits = m.group(1), m.group(2), float(m.group(3)), float(m.group(4))
            if item not in best or psnr > best[item][0]:
                best[item] = (psnr, basis, bits)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("relit")
    ap.add_argument("--data", default=str(ROOT.parent / "shared/data/realrti"))
    ap.add_argument("--baseline", default=str(ROOT.parent / "shared/reference/peer_baseline.md"))
    ap.add_argument("--items", default="item1,item2,item3,item5,item6,item7,item9,item11")
    ap.add_argument("--out", default=str(ROOT / "docs/rd"))
    ap.add_argument("--budget", type=float, default=24.0)
    ap.add_argument("--force", action="store_true")
    a, extra = ap.parse_known_args()
    a.extra = [x for x in extra if x != "--"]
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    reports = {}
    for item in a.items.split(","):
        path = out / f"{item}.json"
        if a.force or not path.exists():
            cmd = [a.relit, "eval", str(pathlib.Path(a.data) / item / "dirs.lp"), "--rd",
                   "--json"] + a.extra
            start = time.time()
            text = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            path.write_text(text)
            print(f"{item}: {time.time() - start:.0f} s", file=sys.stderr, flush=True)
        # The plot is drawn from the stored report, so that a stored curve can be redrawn.
        subprocess.run([a.relit, "eval", "--rd-report", str(path), "--plot", str(out / f"{item}.svg"), "-q"],
                       check=True, capture_output=True)
        reports[item] = json.loads(path.read_text())

    peer = peer_best(pathlib.Path(a.baseline))
    print(f"| item | best ≤ {a.budget:g} bits/px: dB (bits/px) | basis, settings | peer's best: dB (basis, bits/px) | difference | settings | curve time |")
    print("|---|---|---|---|---|---|---|")
    diffs, ours, theirs = [], [], []
    for item, r in reports.items():
        front = [p for p in r["points"] if p["pareto"]]
        within = [p for p in front if p["bits_per_pixel"] <= a.budget]
        p = within[-1] if within else None
        q = peer.get(item)
        cell = f"{p['psnr_srgb8']:.2f} ({p['bits_per_pixel']:.1f})" if p else "none"
        how = f"{p['basis']}, {p['storage']}" if p else ""
        peer_cell = f"{q[0]:.2f} ({q[1]}, {q[2]:.1f})" if q else "n/a"
        diff = f"{p['psnr_srgb8'] - q[0]:+.2f}" if p and q else ""
        if p and q:
            diffs.append(p["psnr_srgb8"] - q[0])
            ours.append(p["psnr_srgb8"])
            theirs.append(q[0])
        print(f"| {item} | {cell} | {how} | {peer_cell} | {diff} | {r['fits'][0]['settings']} | {r['seconds'] / 60:.1f} min |")
    if diffs:
        n = len(diffs)
        print(f"| mean of {n} | {sum(ours) / n:.2f} | | {sum(theirs) / n:.2f} | {sum(diffs) / n:+.2f} | | |")
    for item, r in reports.items():
        fits = ", ".join(f"{f['basis']} {f['fit_seconds']:.1f} s" for f in r["fits"])
        settings = r["fits"][0]["settings"]
        grid = "the whole grid" if settings == 72 else f"{settings} settings spread over the grid"
        print(f"\n### {item}\n")
        print(f"{r['width']}×{r['height']}, {r['images']} images, held out {r['holdouts']} ({r['protocol']}); "
              f"{len(r['points'])} points ({grid}); a fit: {fits}; curve {r['seconds'] / 60:.1f} min. "
              f"Plot: [rd/{item}.svg](rd/{item}.svg), every point: [rd/{item}.json](rd/{item}.json).\n")
        print(f"![{item}: held-out PSNR against bits/px](rd/{item}.svg)\n")
        print("| bits/px | sRGB8 dB | linear dB | basis | storage |")
        print("|---|---|---|---|---|")
        for p in r["points"]:
            if p["pareto"]:
                print(f"| {p['bits_per_pixel']:.2f} | {p['psnr_srgb8']:.2f} | {p['psnr_linear']:.2f} | {p['basis']} | {p['storage']} |")


if __name__ == "__main__":
    sys.exit(main())
