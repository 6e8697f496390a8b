#!/usr/bin/env python3
"""Load test of the viewer's server (`relit view`): N concurrent clients on loopback.

Starts `relit view FILE` (by default on a small box-scene fit it makes first), then runs
--clients threads for --seconds, each fetching the viewer's files in turn (the page,
scripts, shader, info.json, depth and every plane), one connection per request as a
browser's first load does. Reports requests, failures (any status but 200, any error),
latency percentiles, throughput, and the server's resident memory after --warmup
seconds and at the end. Usage:
    scripts/load_test.py [--relit BIN] [--file FILE.exr] [--clients 50] [--seconds 60]
                         [--warmup 5] [--json OUT]
Exits 1 when a request failed or memory grew more than 10 % after the warm-up.
"""
import argparse, http.client, json, pathlib, re, subprocess, sys, tempfile, threading, time

root = pathlib.Path(__file__).resolve().parent.parent
ap = argparse.ArgumentParser()
ap.add_argument("--relit", default=str(root / "target/release/relit"))
ap.add_argument("--file")
ap.add_argument("--clients", type=int, default=50)
ap.add_argument("--seconds", type=float, default=60)
ap.add_argument("--warmup", type=float, default=5)
ap.add_argument("--json")
opts = ap.parse_args()

tmp = tempfile.TemporaryDirectory()
exr = opts.file
if not exr:
    cap = pathlib.Path(tmp.name) / "cap"
    subprocess.run([opts.relit, "capture", "box", "--lights", "fibonacci:48", "--size", "256x192",
                    "--out", cap, "-q"], check=True)
    exr = str(pathlib.Path(tmp.name) / "box.exr")
    subprocess.run([opts.relit, "fit", cap / "capture.json", "--basis", "sh:16", "-o", exr, "-q"],
                   check=True, stdout=subprocess.DEVNULL)

server = subprocess.Popen([opts.relit, "view", exr, "--port", "0"], stderr=subprocess.PIPE, text=True)
line = server.stderr.readline()
m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
if not m:
    server.kill()
    sys.exit(f"relit view did not start: {line}")
port = int(m.group(1))


def fetch(path):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        c.request("GET", path)
        r = c.getresponse()
        body = r.read()
        return r.status, body
    finally:
        c.close()


status, info = fetch("/data/info.json")
assert status == 200, status
# Every data file info.json names (planes, depth, tables), plus the page's own files.
names = sorted(set(re.findall(r'"([\w./-]+\.(?:png|f16|f32|bin|json))"', info.decode())))
paths = ["/", "/main.js", "/relight.frag", "/data/info.json"] + [
    "/data/" + n for n in names if not n.startswith("/")]
paths = [p for p in paths if fetch(p)[0] == 200]


def rss_kib():
    for row in pathlib.Path(f"/proc/{server.pid}/status").read_text().splitlines():
        if row.startswith("VmRSS:"):
            return int(row.split()[1])
    return 0


latencies, failures, sizes = [], [], [0]
lock = threading.Lock()
stop_at = time.time() + opts.warmup + opts.seconds


def client(i):
    k = i
    while time.time() < stop_at:
        path = paths[k % len(paths)]
        k += 1
        t = time.perf_counter()
        try:
            status, body = fetch(path)
            ok = status == 200
        except Exception as e:  # noqa: BLE001 — every error counts as a failure
            ok, status, body = False, repr(e), b""
        dt = time.perf_counter() - t
        with lock:
            latencies.append(dt)
            sizes[0] += len(body)
            if not ok:
                failures.append((path, status))


threads = [threading.Thread(target=client, args=(i,)) for i in range(opts.clients)]
for t in threads:
    t.start()
time.sleep(opts.warmup)
rss_warm = rss_kib()
with lock:
    warm_count, warm_bytes = len(latencies), sizes[0]
for t in threads:
    t.join()
rss_end = rss_kib()
server.terminate()
server.wait()

lat = sorted(latencies[warm_count:])
count = len(lat)
pct = lambda q: lat[min(count - 1, int(q * count))] * 1000 if count else float("nan")
growth = (rss_end - rss_warm) / max(rss_warm, 1)
report = {
    "clients": opts.clients, "seconds": opts.seconds, "files": len(paths),
    "requests": count, "failures": len(failures), "first_failures": failures[:5],
    "requests_per_s": count / opts.seconds,
    "mib_per_s": (sizes[0] - warm_bytes) / opts.seconds / 2**20,
    "latency_ms": {"p50": pct(0.5), "p90": pct(0.9), "p99": pct(0.99), "max": pct(1.0)},
    "rss_kib_after_warmup": rss_warm, "rss_kib_end": rss_end, "rss_growth": growth,
}
print(f"{opts.clients} clients, {opts.seconds:.0f} s after {opts.warmup:.0f} s warm-up, {len(paths)} files: "
      f"{count} requests ({report['requests_per_s']:.0f}/s, {report['mib_per_s']:.0f} MiB/s), "
      f"{len(failures)} failed; latency p50 {pct(0.5):.1f} ms, p90 {pct(0.9):.1f}, p99 {pct(0.99):.1f}, "
      f"max {pct(1.0):.1f}; server memory {rss_warm / 1024:.1f} MiB after warm-up, "
      f"{rss_end / 1024:.1f} MiB at the end ({growth:+.1%})")
if opts.json:
    pathlib.Path(opts.json).write_text(json.dumps(report, indent=1))
sys.exit(1 if failures or growth > 0.10 else 0)
