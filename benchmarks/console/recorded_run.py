# The shared set-up of the console benchmarks: the real `hilbench serve` in a temporary folder,
# a JSON request helper, and one recorded run of the gap-step campaign of
# tests/bench/analyses_api_test.cpp (its duration and speed the caller's).
import json, os, shutil, subprocess, tempfile, time, urllib.error, urllib.request


class Server:
    def __init__(self, exe, src):
        self.src = src
        self.dir = tempfile.mkdtemp()
        self.proc = subprocess.Popen([exe, "serve", "--listen", "127.0.0.1:0", "--configs", src + "/configs", "--runs-dir", self.dir + "/runs",
                                      "--port-file", self.dir + "/port", "--no-mlock"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        while not os.path.exists(self.dir + "/port"): time.sleep(0.05)
        self.base = "http://127.0.0.1:%d" % int(open(self.dir + "/port").read())

    def req(self, path, body=None):
        r = urllib.request.Request(self.base + path, data=None if body is None else json.dumps(body).encode(), method="GET" if body is None else "POST")
        try:
            with urllib.request.urlopen(r) as f: return json.loads(f.read() or b"{}")
        except urllib.error.HTTPError as e: return json.loads(e.read())

    # Records the test's gap-step campaign (duration_s long, at `speed` x real time); its run id.
    def record_run(self, speed, duration_s=None):
        yaml = open(self.src + "/tests/bench/analyses_api_test.cpp").read().split('R"(')[1].split(')"')[0]
        if duration_s is not None: yaml = yaml.replace("duration_s: 8", "duration_s: %g" % duration_s)
        self.req("/api/start", {"campaign_yaml": yaml, "speed": speed})
        while self.req("/api/status")["state"] != "idle" or self.req("/api/status")["last"] is None: time.sleep(0.1)
        return self.req("/api/runs")["runs"][0]["id"]

    def close(self):
        if self.proc.poll() is None: self.proc.terminate(); self.proc.wait()
        shutil.rmtree(self.dir, ignore_errors=True)
