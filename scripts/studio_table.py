#!/usr/bin/env python3
"""Figures of the capture studio and of every light type on the built-in scenes.

Runs, with the release binary (default target/release/relit):
  1. `relit capture attic --lights fibonacci:1000` (1024x256): wall time and rays/s;
  2. for each scene: a 300-light capture, then `relit eval` of held-out *directional*
     lights (8 captured lights of the upper hemisphere held out together, one fit) at
     SH 16 and 25 coefficients;
  3. for each scene: `relit eval --scene` with the default rig (one light of each type
     against ray-traced truth), with the environment and area-light checks;
  4. `relit demo` and a 120-frame animation replayed with `relit relight --rig`.
Prints Markdown; `--json FILE` also writes every raw result. Usage:
    scripts/studio_table.py [--relit BIN] [--scenes attic,city] [--json FILE] [--quick]
`--quick` skips the 1000-light capture and the demo (about 2 minutes less).
"""
import argparse, json, pathlib, subprocess, sys, tempfile, time

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("--relit", default=str(root / "target/release/relit"))
ap.add_argument("--scenes", default="attic,city")
ap.add_argument("--json")
ap.add_argument("--quick", action="store_true")
ap.add_argument("--basis", default="sh:25", help="basis of the every-light-type table")
opts = ap.parse_args()
relit = opts.relit
results = {}


def run(*args):
    t = time.time()
    out = subprocess.run([relit, *map(str, args)], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"relit {' '.join(map(str, args))} failed:\n{out.stderr}")
    return out.stdout, time.time() - t


def log(msg):
    print(msg, file=sys.stderr, flush=True)


with tempfile.TemporaryDirectory() as tmp:
    tmp = pathlib.Path(tmp)
    if not opts.quick:
        log("capture: attic, 1000 lights")
        out, wall = run("capture", "attic", "--lights", "fibonacci:1000", "--out", tmp / "c1000", "--json", "-q")
        r = json.loads(out)
        results["capture_1000"] = {**r, "wall_seconds": wall}
        print("## Capture\n")
        print("| scene | size | lights | triangles | wall s | lighting s | shadow rays | Mrays/s |")
        print("|---|---|---|---|---|---|---|---|")
        print(f"| attic | {r['width']}×{r['height']} | {r['lights']} | {r['triangles']} | {wall:.1f} "
              f"| {r['lighting_seconds']:.1f} | {r['shadow_rays'] / 1e6:.0f} M | {r['rays_per_second'] / 1e6:.2f} |\n")
        subprocess.run(["rm", "-rf", str(tmp / "c1000")])

    print("## Held-out directional lights (300 captured, 8 of the upper hemisphere held out, one joint fit)\n")
    print("| scene | coefficients | objective | λ | sRGB8 dB | linear dB | fit s |")
    print("|---|---|---|---|---|---|---|")
    for scene in opts.scenes.split(","):
        log(f"capture: {scene}, 300 lights")
        cap = tmp / f"{scene}300"
        run("capture", scene, "--lights", "fibonacci:300", "--out", cap, "-q")
        manifest = json.loads((cap / "capture.json").read_text())
        upper = [i for i, im in enumerate(manifest["images"]) if im["direction"][1] > 0.1]
        held = [upper[round(i * (len(upper) - 1) / 7)] for i in range(8)]
        for bands in (4, 5):
            log(f"eval: {scene}, {bands * bands} coefficients")
            out, _ = run("eval", cap / "capture.json", "--holdout", ",".join(map(str, held)), "--joint",
                         "--basis", f"sh:{bands * bands}", "--json", "-q")
            r = json.loads(out)
            results[f"holdout_{scene}_{bands}"] = r
            h = r["holdouts"][0]
            print(f"| {scene} | {bands * bands} | {r['objective']} | {h.get('lambda', float('nan')):.0e} "
                  f"| {r['psnr_srgb8_mean']:.2f} | {r['psnr_linear_mean']:.2f} | {r['fit_seconds']:.1f} |", flush=True)
        subprocess.run(["rm", "-rf", str(cap)])

    print("\n## Every light type against ray-traced truth (`relit eval --scene`, 300 captured lights, 25 coefficients)\n")
    evals = {}
    for scene in opts.scenes.split(","):
        log(f"eval --scene {scene}")
        out, wall = run("eval", "--scene", scene, "--basis", opts.basis, "--json", "-q")
        evals[scene] = json.loads(out)
        evals[scene]["wall_seconds"] = wall
    results["scene_eval"] = evals
    scenes = list(evals)
    print(f"basis {opts.basis}, objective " + ", ".join(f"{s}: {evals[s]['fit']['objective']}" for s in scenes) + "\n")
    print("| light | " + " | ".join(f"{s} linear dB | {s} sRGB8 dB | {s} relit/truth mean" for s in scenes) + " | relight ms (" + scenes[0] + ") |")
    print("|---|" + "---|---|---|" * len(scenes) + "---|")
    for i, light in enumerate(evals[scenes[0]]["lights"]):
        cells = []
        for s in scenes:
            l = evals[s]["lights"][i]
            cells.append(f"{l['psnr_linear']:.2f} | {l['psnr_srgb8']:.2f} | {l['relit_mean'] / l['truth_mean']:.3f}")
        print(f"| {light['type']} | " + " | ".join(cells) + f" | {1e3 * light['relight_seconds']:.1f} |")

    print("\nOcclusion limitation (seed 004 §VI): pixels whose light is blocked *beyond* the light, linear dB\n")
    print("| scene | light | affected pixels | PSNR affected | PSNR elsewhere |")
    print("|---|---|---|---|---|")
    for s in scenes:
        for l in evals[s]["lights"]:
            o = l.get("occlusion")
            if o:
                a = o["affected"]["psnr_linear"] if o.get("affected") else float("nan")
                c = o["clear"]["psnr_linear"] if o.get("clear") else float("nan")
                print(f"| {s} | {l['type']} | {100 * o['affected_fraction']:.1f} % | {a:.2f} | {c:.2f} |")

    print("\nEnvironment light against brute force Σ_j w_j I_j over the captured images, linear dB against truth\n")
    print("| scene | window | SH dot product | brute force, same band-limited light | gap | brute force, raw map | SH vs raw |")
    print("|---|---|---|---|---|---|---|")
    for s in scenes:
        for e in evals[s]["environment"]:
            print(f"| {s} | {e['window']['type']} | {e['relit']['psnr_linear']:.2f} | {e['brute_force']['psnr_linear']:.2f} "
                  f"| {e['gain_linear_db']:+.2f} | {e['brute_force_raw']['psnr_linear']:.2f} | {e['gain_vs_raw_linear_db']:+.2f} |")

    print("\nArea light: emitter samples per pixel against a converged relight and against truth, linear dB\n")
    print("| scene | samples | vs converged | vs truth | relight ms |")
    print("|---|---|---|---|---|")
    for s in scenes:
        for a in evals[s]["area"]:
            print(f"| {s} | {a['samples']} | {a['vs_converged']['psnr_linear']:.2f} | {a['vs_truth']['psnr_linear']:.2f} "
                  f"| {1e3 * a['relight_seconds']:.1f} |")

    if not opts.quick:
        log("demo")
        out, wall = run("demo", "--out", tmp / "demo", "--json")
        d = json.loads(out[out.index("{"):])
        results["demo"] = {**d, "wall_seconds": wall}
        log("animation: 120 frames")
        out, anim = run("relight", tmp / "demo/scene.exr", "--rig", tmp / "demo/lamp-animation.json",
                        "--frames", 120, "--out", tmp / "frames")
        results["animation_120_seconds"] = anim
        print("\n## Demo and animation\n")
        print(f"`relit demo`: {wall:.1f} s wall (capture {d['capture']['seconds']:.1f} s, fit {d['fit']['seconds']:.1f} s); "
              f"moving sun {d['sun']['psnr_linear_mean']:.2f} dB linear / {d['sun']['psnr_srgb8_mean']:.2f} dB sRGB8, "
              f"lamp {d['lamp']['psnr_linear_mean']:.2f} / {d['lamp']['psnr_srgb8_mean']:.2f} dB against ray-traced truth.\n")
        print(f"`relit relight scene.exr --rig lamp-animation.json --frames 120 --out frames/`: {anim:.2f} s wall "
              f"({1e3 * anim / 120:.1f} ms per frame, PNG writing and process start included).")

if opts.json:
    pathlib.Path(opts.json).write_text(json.dumps(results, indent=1))
