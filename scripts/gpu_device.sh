#!/usr/bin/env bash
# The GPU checks a CPU-only machine cannot make, in one run on a machine with a hardware
# adapter: the GPU engine's tests against the CPU engine on that adapter, `relit relight
# --gpu --compare` on real fits, and `relit bench`'s GPU rows (every case and storage,
# several bases, 1024×256 and 8192×2048) set against the device's own read rate.
#
#   scripts/gpu_device.sh RELIT GPU_TESTS [FILE...]
#
# RELIT is a `relit` binary, GPU_TESTS the `gpu_vs_cpu` test binary of relit-gpu
# (`cargo test --release -p relit-gpu --no-run` prints its path), FILE a relightable
# file (.exr, .rlz) to compare on. Results go to $OUT (or target/gpu-device): the
# adapter list, the test log, the comparisons and one bench JSON per size, and a
# summary table at the end of the output. Each step has its own time limit so that a
# slow one leaves the others' results. RELIT_GPU_SIZES overrides the bench sizes.
set -uo pipefail
relit=${1:?usage: scripts/gpu_device.sh RELIT GPU_TESTS [FILE...]}
tests=${2:?usage: scripts/gpu_device.sh RELIT GPU_TESTS [FILE...]}
shift 2
out=${OUT:-target/gpu-device}
mkdir -p "$out"
export RELIT_NO_SKIPS=1

{ nvidia-smi -L 2>/dev/null; "$relit" doctor; } 2>&1 | tee "$out/doctor.txt"

echo "== GPU engine tests (every basis and light type against the CPU engine)"
timeout 120 "$tests" --test-threads=1 2>&1 | tee "$out/tests.txt" | tail -14

echo "== relight --gpu --compare on real fits"
for file in "$@"; do
  for light in dir:0.3,0.4,0.8 dir:-0.6,0.2,0.5 'dir:0,0,1'; do
    echo "$file $light"
    for storage in f32 f16 u8; do
      timeout 60 "$relit" relight "$file" --light "$light" -o "$out/frame.png" \
        --gpu --storage "$storage" --compare 2>&1 | grep -v '^wrote'
    done
  done
done 2>&1 | tee "$out/compare.txt"
rm -f "$out/frame.png"

bases=(--basis sh:16 --basis sh:25 --basis hsh:16 --basis sg:25 --basis ptm:6 --basis rbf:25 --basis bilinear:25)
for size in ${RELIT_GPU_SIZES:-1024x256 8192x2048}; do
  echo "== relit bench --no-cpu --size $size"
  timeout 200 "$relit" bench --no-cpu --json --seconds 0.25 --size "$size" "${bases[@]}" \
    >"$out/bench-$size.json" 2>"$out/bench-$size.log"
  echo "rc=$? ($(grep -c '"case"' "$out/bench-$size.json" 2>/dev/null || echo 0) rows)"
done

python3 - "$out" <<'EOF'
import json, pathlib, sys
out = pathlib.Path(sys.argv[1])
for path in sorted(out.glob("bench-*.json")):
    try:
        rows = json.loads(path.read_text())
    except ValueError:
        print(f"{path.name}: no complete JSON")
        continue
    print(f"{path.name}: {rows[0]['engine'] if rows else ''}")
    print(f"{'case':12} {'basis':12} {'stor':4} {'fps':>9} {'GB/s bound':>10} {'of bound':>8}")
    for r in rows:
        frac = r.get("bandwidth_fraction")
        print(f"{r['case']:12} {r['basis']:12} {r['storage']:4} {r['fps']:9.1f} "
              f"{r['read_bandwidth_gbs']:10.0f} {'' if frac is None else f'{frac:8.2f}'}")
EOF
