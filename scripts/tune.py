#!/usr/bin/env python3
"""Compare fit settings on tuning hold-outs that are NOT the ones reported.

The reported protocol holds out round(i*(N-1)/4), i=0..4. Tuning uses the midpoints
between them, round((i+0.5)*(N-1)/5), so no default is chosen on a reported figure.
Usage: scripts/tune.py RELIT_BINARY ITEMS_DIR 'label:--flags' ...
"""
import json, subprocess, sys, pathlib

relit, items_dir, configs = sys.argv[1], pathlib.Path(sys.argv[2]), sys.argv[3:]
rows = []
for lp in sorted(items_dir.glob("item*/dirs.lp"), key=lambda p: int(p.parent.name[4:])):
    n = int(lp.read_text().split()[0])
    tune = sorted({round((i + 0.5) * (n - 1) / 5) for i in range(5)})
    line = [lp.parent.name]
    for cfg in configs:
        label, flags = cfg.split(":", 1)
        out = subprocess.run([relit, "eval", str(lp), "--json", "--holdout", ",".join(map(str, tune))] + flags.split(),
                             capture_output=True, text=True, check=True)
        r = json.loads(out.stdout)
        line.append(f"{label}={r['psnr_srgb8_mean']:.2f}")
    print("  ".join(line), flush=True)
