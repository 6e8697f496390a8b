#!/usr/bin/env python3
"""How well the RTI tools' files relit writes reproduce held-out photographs.

For every ../shared/data/realrti item: a capture without the peer protocol's five
hold-outs (indices round(i*(N-1)/4)) is fitted by each given binary with its defaults
and written as `.rti` (or `--ext ptm`); `relit eval ITEM --file F --holdout …` then
scores the file at the held-out lights (8-bit sRGB PSNR over the frame, the file's own
display values). Prints one column per binary. Usage:
    scripts/rti_files.py BINARY [BINARY ...] [--ext rti|ptm] [--keep DIR]
"""
import argparse, json, pathlib, subprocess, tempfile

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("binaries", nargs="+")
ap.add_argument("--ext", default="rti", choices=["rti", "ptm"])
ap.add_argument("--keep", help="folder for the training .lp files and the written files")
args = ap.parse_args()
data = root.parent / "shared/data/realrti"
work = pathlib.Path(args.keep) if args.keep else pathlib.Path(tempfile.mkdtemp())
items = sorted((p.name for p in data.glob("item*")), key=lambda s: int(s[4:]))
print("| item | " + " | ".join(args.binaries) + " |")
print("|---|" + "---|" * len(args.binaries))
totals = [0.0] * len(args.binaries)
for item in items:
    lp = data / item / "dirs.lp"
    lines = [l for l in lp.read_text().splitlines() if l.strip()]
    n = int(lines[0])
    held = sorted({round(i * (n - 1) / 4) for i in range(5)})
    train = [r for i, r in enumerate(lines[1:1 + n]) if i not in held]
    folder = work / item
    folder.mkdir(parents=True, exist_ok=True)
    train_lp = folder / "train.lp"
    train_lp.write_text(f"{len(train)}\n" + "\n".join(
        f"{data / item / r.split()[0]} {' '.join(r.split()[1:])}" for r in train) + "\n")
    scores = []
    for b, binary in enumerate(args.binaries):
        out = folder / f"fit{b}.{args.ext}"
        out.unlink(missing_ok=True)
        subprocess.run([binary, "fit", str(train_lp), "-o", str(out), "-q"], check=True,
                       capture_output=True)
        r = json.loads(subprocess.run(
            [args.binaries[-1], "eval", str(lp), "--file", str(out), "--holdout",
             ",".join(map(str, held)), "--json", "-q"],
            check=True, capture_output=True, text=True).stdout)
        scores.append(r["psnr_srgb8_mean"])
        totals[b] += r["psnr_srgb8_mean"]
    print(f"| {item} | " + " | ".join(f"{s:.2f}" for s in scores) + " |", flush=True)
print("| mean | " + " | ".join(f"{t / len(items):.2f}" for t in totals) + " |")
