#!/usr/bin/env python3
"""relit's default fit against relight-cli's HSH-27 fit as a capture grows.

For each size, writes the item's capture repeated, mirrored and jittered to that size
(`relit bench --write-capture`), then runs `relit bench --fit DIR/dirs.lp --peer PEER
--json` RUNS times (each run times both tools from process start to file written, with
their peak memory) and prints a Markdown table: the fastest relit run over the fastest
peer run, and the largest peaks. Usage:
    scripts/fit_by_size.py --peer PATH/relight-cli [--relit BIN] [--item ITEM_DIR]
        [--sizes 640x480,1024x768] [--runs 2] [--keep DIR]
The item itself (its own size) is the first row.
"""
import argparse, json, pathlib, subprocess, sys, tempfile

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--peer", required=True, help="relight-cli binary")
ap.add_argument("--relit", default=str(root / "target/release/relit"))
ap.add_argument("--item", default=str(root.parent / "shared/data/realrti/item1"))
ap.add_argument("--sizes", default="640x480,800x600,1024x768,1600x1200,2048x1536")
ap.add_argument("--runs", type=int, default=2)
ap.add_argument("--keep", help="write the grown captures here (default: a temporary folder)")
args = ap.parse_args()

item = pathlib.Path(args.item)
work = pathlib.Path(args.keep) if args.keep else pathlib.Path(tempfile.mkdtemp(prefix="fit_by_size."))
work.mkdir(parents=True, exist_ok=True)


def fit(capture):
    runs = []
    for _ in range(args.runs):
        out = subprocess.run([args.relit, "bench", "--fit", str(capture / "dirs.lp"), "--peer", args.peer, "--json"],
                             capture_output=True, text=True, check=True)
        runs.append(json.loads(out.stdout))
    return runs


print("| capture | relit s | relight-cli s | time × | relit MiB | relight-cli MiB | memory × | relit's basis |")
print("|---|---:|---:|---:|---:|---:|---:|---|")
captures = [(f"{item.name} (its own size)", item)]
for size in [s for s in args.sizes.split(",") if s]:
    grown = work / f"{item.name}_{size}"
    if not (grown / "dirs.lp").exists():
        subprocess.run([args.relit, "bench", "--write-capture", str(grown), "--capture-from", str(item / "dirs.lp"),
                        "--size", size], capture_output=True, text=True, check=True)
    captures.append((f"{item.name} → {size}", grown))
for name, capture in captures:
    runs = fit(capture)
    relit_s = min(r["relit"]["wall_seconds"] for r in runs)
    peer_s = min(r["peer"]["wall_seconds"] for r in runs)
    relit_mib = max(r["relit"]["peak_rss_bytes"] for r in runs) / 2**20
    peer_mib = max(r["peer"]["peak_rss_bytes"] for r in runs) / 2**20
    print(f"| {name} | {relit_s:.2f} | {peer_s:.2f} | {relit_s / peer_s:.2f} | {relit_mib:.1f} | {peer_mib:.1f} "
          f"| {relit_mib / peer_mib:.2f} | {runs[0]['relit_fit']['basis']} |", flush=True)
if not args.keep:
    print(f"\n(captures written under {work}; remove it when done)", file=sys.stderr)
