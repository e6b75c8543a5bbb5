# GET /api/status latency of the real `hilbench serve` with its job worker idle, and while a
# diagnosis of a recorded run runs on it (docs/benchmarks.md, Operator console). The run is the
# gap-step campaign of tests/bench/analyses_api_test.cpp (8 s at 1 kHz, recorded at speed 4).
#   python3 benchmarks/console/status_during_job.py build/bench/hilbench .
import sys, time
from recorded_run import Server
exe, src = sys.argv[1], sys.argv[2]
srv = Server(exe, src)
req = srv.req
run = srv.record_run(speed=4)
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
srv.close()
