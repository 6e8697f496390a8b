#!/usr/bin/env python3
"""Baked transfer (`relit bake`) against captured-and-fitted maps on the attic.

Both routes against the ray-traced truth (`relit render-truth`) under the environment
maps of ../shared/data/envmaps, measured with `relit compare --json`:
  1. image route: `relit capture attic --lights fibonacci:300`, `relit fit --basis sh:25`;
  2. baked: `relit bake attic --transfer diffuse --bands 5` (the default Laplacian
     window; also without a window, and Lambertian only), `--transfer bleeding` against `render-truth --indirect`.
Prints Markdown, writes the raw results as JSON and the pictures as PNG. Usage:
    scripts/transfer_table.py [--relit BIN] [--size 512x128] [--out docs/transfer]
        [--indirect-maps pedestrian_overpass,royal_esplanade,venice_sunset]
"""
import argparse, json, pathlib, subprocess, sys, tempfile, time

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("--relit", default=str(root / "target/release/relit"))
ap.add_argument("--size", default="512x128")
ap.add_argument("--envmaps", default=str(root.parent / "shared/data/envmaps"))
ap.add_argument("--indirect", type=int, default=16, help="bounce rays per sample")
ap.add_argument("--indirect-maps", default="pedestrian_overpass,royal_esplanade,venice_sunset")
ap.add_argument("--picture-map", default="pedestrian_overpass")
ap.add_argument("--out", default=str(root / "docs/transfer"))
opts = ap.parse_args()
out_dir = pathlib.Path(opts.out)
out_dir.mkdir(parents=True, exist_ok=True)
maps = sorted(p for p in pathlib.Path(opts.envmaps).glob("*.hdr"))
if not maps:
    sys.exit(f"no .hdr maps in {opts.envmaps}")


def run(*args):
    t = time.time()
    out = subprocess.run([opts.relit, *map(str, args)], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"relit {' '.join(map(str, args))} failed:\n{out.stderr}")
    return out.stdout, time.time() - t


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def name(path):
    return path.stem.removesuffix("_1k")


results = {"size": opts.size, "indirect": opts.indirect, "routes": {}, "scores": []}
with tempfile.TemporaryDirectory() as tmp:
    tmp = pathlib.Path(tmp)
    size = ["--size", opts.size]

    log("image route: capture 300 lights, fit sh:25")
    _, capture_s = run("capture", "attic", "--lights", "fibonacci:300", *size, "--out", tmp / "cap", "-q")
    _, fit_s = run("fit", tmp / "cap/capture.json", "--basis", "sh:25", "-o", tmp / "fit.exr", "-q")
    files = {"fit sh:25": tmp / "fit.exr"}
    results["routes"]["fit sh:25"] = {
        "seconds": capture_s + fit_s,
        "capture_seconds": capture_s,
        "fit_seconds": fit_s,
        "bytes": (tmp / "fit.exr").stat().st_size,
    }
    bakes = {
        "bake diffuse": ["--transfer", "diffuse"],
        "bake diffuse, no window": ["--transfer", "diffuse", "--window", "none"],
        "bake diffuse, Lambertian only": ["--transfer", "diffuse", "--lambert"],
        "bake bleeding": ["--transfer", "bleeding", "--indirect", opts.indirect],
    }
    for label, args in bakes.items():
        log(label)
        path = tmp / (label.replace(" ", "_").replace(",", "") + ".exr")
        summary, wall = run("bake", "attic", *size, "--bands", 5, *args, "-o", path, "--json", "-q")
        s = json.loads(summary)
        files[label] = path
        results["routes"][label] = {
            "seconds": wall,
            "bake_seconds": s["total_seconds"],
            "bytes": path.stat().st_size,
            "relative_noise": s["relative_noise"],
            "rays": s["rays"],
        }

    indirect_maps = set(opts.indirect_maps.split(","))
    for env in maps:
        env_name = name(env)
        rig = tmp / f"{env_name}.json"
        rig.write_text(json.dumps({"lights": [{"type": "environment", "map": str(env)}]}))
        truths = {"direct": tmp / f"truth_{env_name}.exr"}
        log(f"{env_name}: ray-traced truth")
        _, truth_s = run("render-truth", "attic", *size, "--rig", rig, "-o", truths["direct"], "-q")
        if env_name in indirect_maps:
            truths["indirect"] = tmp / f"truth_{env_name}_indirect.exr"
            run("render-truth", "attic", *size, "--rig", rig, "--indirect", opts.indirect,
                "-o", truths["indirect"], "-q")
        for label, path in files.items():
            lit = tmp / "lit.exr"
            run("relight", path, "--rig", rig, "-o", lit)
            for truth_kind, truth in truths.items():
                if label == "bake bleeding" and truth_kind == "direct":
                    continue  # bleeding is measured against the truth with bounces
                c = json.loads(run("compare", lit, truth, "--json")[0])
                results["scores"].append({
                    "map": env_name, "route": label, "truth": truth_kind,
                    "psnr_linear": c["psnr_linear"], "psnr_srgb8": c["psnr_srgb8"],
                    "ssim": c["ssim"], "mean_abs_error": c["mean_abs_error"],
                })
        if env_name == opts.picture_map:
            pictures = {
                "truth.png": ("render-truth", truths["direct"]),
                "fit-sh25.png": ("relight", files["fit sh:25"]),
                "bake-diffuse.png": ("relight", files["bake diffuse"]),
            }
            if "indirect" in truths:
                pictures["truth-indirect.png"] = ("render-truth", truths["indirect"])
                pictures["bake-bleeding.png"] = ("relight", files["bake bleeding"])
            for picture, (how, source) in pictures.items():
                target = out_dir / picture
                if how == "render-truth":
                    extra = ["--indirect", opts.indirect] if "indirect" in picture else []
                    run("render-truth", "attic", *size, "--rig", rig, *extra, "-o", target, "-q")
                else:
                    run("relight", source, "--rig", rig, "-o", target)
            for label, source in (("fit-sh25", files["fit sh:25"]), ("bake-diffuse", files["bake diffuse"])):
                lit = tmp / "lit.exr"
                run("relight", source, "--rig", rig, "-o", lit)
                run("compare", lit, truths["direct"], "--diff", out_dir / f"diff-{label}.png")

(out_dir / "table.json").write_text(json.dumps(results, indent=1))

print(f"## Attic {opts.size}, SH 25 coefficients (5 bands)\n")
print("| route | seconds | bytes | sampling noise |")
print("|---|---:|---:|---:|")
for label, r in results["routes"].items():
    noise = f"{100 * r['relative_noise']:.2f} %" if "relative_noise" in r else "—"
    print(f"| {label} | {r['seconds']:.2f} | {r['bytes']:,} | {noise} |")
print()
for truth_kind in ("direct", "indirect"):
    rows = [s for s in results["scores"] if s["truth"] == truth_kind]
    if not rows:
        continue
    routes = list(dict.fromkeys(s["route"] for s in rows))
    print(f"### Against the {truth_kind} ray-traced truth: PSNR linear / 8-bit sRGB (dB)\n")
    print("| map | " + " | ".join(routes) + " |")
    print("|---|" + "---:|" * len(routes))
    for env in dict.fromkeys(s["map"] for s in rows):
        cells = []
        for route in routes:
            s = next((s for s in rows if s["map"] == env and s["route"] == route), None)
            cells.append(f"{s['psnr_linear']:.2f} / {s['psnr_srgb8']:.2f}" if s else "—")
        print(f"| {env} | " + " | ".join(cells) + " |")
    print()
