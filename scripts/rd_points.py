#!/usr/bin/env python3
"""Rate–distortion points of the compressed file on RTI captures (peer protocol).

Runs `relit eval ITEM --json` once per item and setting (the uncompressed half-float
EXR first, then each `--compressed` setting): every point is a real .rlz file written,
read back and relit at the held-out lights; bits/pixel is its size on disk.

    scripts/rd_points.py target/release/relit [--items item1,item3] [--basis sh:25]
        [--setting "--layout ycc --components 9 --chroma 3 --codec jpeg:90" ...]
        [--json out.json]
"""
import argparse, json, subprocess, sys, pathlib

DEFAULT_SETTINGS = [
    "--layout ycc --components 9 --chroma 3 --bits 8",
    "--layout ycc --components 9 --chroma 3 --codec jpeg:90",
    "--layout ycc --components 6 --chroma 2 --codec jpeg:85",
    "--layout lrgb --components 6 --codec jpeg:85",
]

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("relit")
    ap.add_argument("--data", default=str(pathlib.Path(__file__).resolve().parents[2] / "shared/data/realrti"))
    ap.add_argument("--items", default="item1,item2,item3,item5,item6,item7,item9,item11")
    ap.add_argument("--basis", default="auto")
    ap.add_argument("--setting", action="append")
    ap.add_argument("--json")
    a = ap.parse_args()
    settings = [None] + (a.setting or DEFAULT_SETTINGS)
    rows = []
    for item in a.items.split(","):
        lp = pathlib.Path(a.data) / item / "dirs.lp"
        for s in settings:
            cmd = [a.relit, "eval", str(lp), "--json", "--basis", a.basis]
            if s:
                cmd += ["--compressed"] + s.split()
            r = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
            row = {"item": item, "setting": s or "exr f16", "basis": r["basis"],
                   "psnr_srgb8": r["psnr_srgb8_mean"], "bits_per_pixel": 8 * r["bytes_per_pixel"]}
            rows.append(row)
            print(f"{item:7} {row['setting']:58} {row['basis']:14} {row['psnr_srgb8']:6.2f} dB {row['bits_per_pixel']:7.1f} bits/px", flush=True)
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(rows, indent=1))

if __name__ == "__main__":
    sys.exit(main())
