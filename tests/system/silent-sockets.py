#!/usr/bin/env python3
"""Opens 300 silent sockets to a `pmcodec serve` started with a 256-descriptor limit and times
/healthz. Not part of the test run (it waits up to 40 s):

    python3 tests/system/silent-sockets.py target/debug/pmcodec 18333 [--max-connections 200]
"""
import socket, subprocess, sys, time, urllib.request
bin_, port, extra = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
p = subprocess.Popen(["bash", "-c", f"ulimit -n 256; exec {bin_} -q serve --listen 127.0.0.1:{port} --no-viewer " + " ".join(extra)], env={"PATH": "/usr/bin:/bin", "PMCODEC_LOG": "error", "PMCODEC_STORE": "memory"})
base = f"http://127.0.0.1:{port}"
for _ in range(300):
    try:
        if urllib.request.urlopen(base + "/healthz", timeout=1).status == 200: break
    except Exception: time.sleep(0.1)
socks = []
for _ in range(300):
    s = socket.create_connection(("127.0.0.1", port)); socks.append(s)
t = time.time()
try:
    r = urllib.request.urlopen(base + "/healthz", timeout=40); print("healthz with 300 idle sockets open:", r.status, "after", round(time.time() - t, 1), "s")
except Exception as e:
    print("healthz with 300 idle sockets open: no answer within", round(time.time() - t, 1), "s:", e)
p.terminate(); p.wait()
