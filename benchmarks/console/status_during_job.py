# GET /api/status latency of the real `hilbench serve` with its job worker idle, and while a
# diagnosis of a recorded run runs on it (docs/benchmarks.md, Operator console). The run is the
# gap-step campaign of tests/bench/analyses_api_test.cpp (8 s at 1 kHz, recorded at speed 4).
#   python3 benchmarks/console/status_during_job.py build/bench/hilbench .
import json, os, shutil, subprocess, sys, tempfile, time, urllib.request
exe, src = sys.argv[1], sys.argv[2]
d = tempfile.mkdtemp()
p = subprocess.Popen([exe, "serve", "--listen", "127.0.0.1:0", "--configs", src + "/configs", "--runs-dir", d + "/runs", "--port-file", d + "/port", "--no-mlock"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
while not os.path.exists(d + "/port"): time.sleep(0.05)
base = "http://127.0.0.1:%d" % int(open(d + "/port").read())
def req(path, body=None):
    r = urllib.request.Request(base + path, data=None if body is None else json.dumps(body).encode(), method="GET" if body is None else "POST")
    try:
        with urllib.request.urlopen(r) as f: return json.loads(f.read() or b"{}")
    except urllib.error.HTTPError as e: return json.loads(e.read())
yaml = open(src + "/tests/bench/analyses_api_test.cpp").read().split('R"(')[1].split(')"')[0]
req("/api/start", {"campaign_yaml": yaml, "speed": 4})
while req("/api/status")["state"] != "idle" or req("/api/status")["last"] is None: time.sleep(0.1)
run = req("/api/runs")["runs"][0]["id"]
def lat(n):
    out = []
    for _ in range(n):
        t = time.perf_counter(); req("/api/status"); out.append((time.perf_counter() - t) * 1e3)
    return out
idle = lat(200)
a = req("/api/runs/%s/analyses" % run, {"kind": "diagnose", "model": "nominal"})["analysis"]["id"]
while True:
    s = [x for x in req("/api/runs/%s/analyses" % run)["analyses"] if x["id"] == a][0]
    if s["state"] == "running": break
busy, n_running = [], 0
while True:
    busy += lat(10)
    s = [x for x in req("/api/runs/%s/analyses" % run)["analyses"] if x["id"] == a][0]
    if s["state"] != "running": break
    n_running = len(busy)
q = lambda v, f: sorted(v)[int(f * (len(v) - 1))]
print("idle:    n=%d p50=%.2f ms p99=%.2f ms max=%.2f ms" % (len(idle), q(idle, .5), q(idle, .99), max(idle)))
print("diagnose running (%s -> %s): n=%d answered while running, p50=%.2f ms p99=%.2f ms max=%.2f ms" % (s["started_utc"], s["finished_utc"], n_running, q(busy, .5), q(busy, .99), max(busy)))
p.terminate(); p.wait()
shutil.rmtree(d, ignore_errors=True)
