# How long SIGTERM takes to end `hilbench serve` while a diagnosis runs on its job worker, against
# the diagnosis's own length (docs/benchmarks.md, Operator console). The run is the gap-step
# campaign of tests/bench/analyses_api_test.cpp, DURATION_S long (default 300 s at 1 kHz, recorded
# at speed 50); one diagnosis runs to its end for its length, a second gets SIGTERM DELAY_S into it.
#   python3 benchmarks/console/stop_during_diagnosis.py build/bench/hilbench . [DURATION_S] [DELAY_S]
import os, signal, sys, time
from recorded_run import Server
exe, src = sys.argv[1], sys.argv[2]
duration_s = float(sys.argv[3]) if len(sys.argv) > 3 else 300
delay_s = float(sys.argv[4]) if len(sys.argv) > 4 else 0.5
srv = Server(exe, src)
req, p = srv.req, srv.proc
run = srv.record_run(speed=50, duration_s=duration_s)
def state(a): return req("/api/runs/%s/analyses/%s" % (run, a))["analysis"]
t = time.perf_counter()
a = req("/api/runs/%s/analyses" % run, {"kind": "diagnose", "model": "nominal"})["analysis"]["id"]
while state(a)["state"] not in ("done", "failed"): time.sleep(0.01)
full_s = time.perf_counter() - t
b = req("/api/runs/%s/analyses" % run, {"kind": "diagnose", "model": "nominal"})["analysis"]["id"]
while state(b)["state"] != "running": time.sleep(0.01)
time.sleep(delay_s)
t = time.perf_counter(); p.send_signal(signal.SIGTERM); p.wait(); stop_s = time.perf_counter() - t
folder = "%s/runs/%s/analyses/%s" % (srv.dir, run, b)
left = sorted(os.listdir(folder)) if os.path.isdir(folder) else []
print("%g s run: diagnosis %.2f s; SIGTERM %.1f s into the next one -> exit in %.3f s, exit status %d, %s left %s" % (duration_s, full_s, delay_s, stop_s, p.returncode, b, left))
srv.close()
