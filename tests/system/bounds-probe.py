#!/usr/bin/env python3
"""Probes a `pmcodec serve` binary for the issue-13 bounds, over loopback sockets: an idle
keep-alive socket and a slow-loris header are closed, immutable URLs are private under a read
token, HEAD /mesh runs no decode, long URLs are not echoed, fps is bounded, DELETE /v1/jobs/{id}
exists, nosniff is sent, and an empty write token is refused. Not part of the test run (the
same checks are tests in crates/pmcodec-server/tests/api.rs and tests/system/server.rs); for
comparing binaries, e.g. before and after a change:

    python3 tests/system/bounds-probe.py target/debug/pmcodec 18302 --idle-timeout 3 --header-read-timeout 3
"""
import socket, subprocess, sys, time, os, json, urllib.request, tempfile
bin_, port, extra = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
assets = tempfile.mkdtemp()
env = dict(os.environ, PMCODEC_WRITE_TOKEN="t", PMCODEC_READ_TOKEN="r", PMCODEC_LOG="error")
p = subprocess.Popen([bin_, "-q", "serve", "--listen", f"127.0.0.1:{port}", "--no-viewer"] + extra, env=env)
base = f"http://127.0.0.1:{port}"
for _ in range(600):
    try:
        if urllib.request.urlopen(base + "/readyz").status == 200: break
    except Exception: time.sleep(0.1)
def req(method, path, body=None, headers={}):
    r = urllib.request.Request(base + path, data=body, method=method, headers={"Authorization": "Bearer r", **headers})
    try:
        with urllib.request.urlopen(r) as resp: return resp.status, dict(resp.headers), resp.read()
    except urllib.error.HTTPError as e: return e.code, dict(e.headers), e.read()
def closed_within(s, secs):
    s.settimeout(secs); t = time.time()
    try:
        while True:
            d = s.recv(1024)
            if not d: return round(time.time() - t, 1)
    except socket.timeout: return None
    except OSError: return round(time.time() - t, 1)
# idle keep-alive
s = socket.create_connection(("127.0.0.1", port)); s.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n"); s.recv(1024)
print("idle keep-alive socket closed after (s):", closed_within(s, 12))
# slow loris: a header byte every 0.5 s for 12 s
s = socket.create_connection(("127.0.0.1", port)); s.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n"); t = time.time(); cut = None
while time.time() - t < 12:
    try: s.sendall(b"a"); s.settimeout(0.5); d = s.recv(1024)
    except socket.timeout: continue
    except OSError: cut = round(time.time() - t, 1); break
    if not d: cut = round(time.time() - t, 1); break
print("slow-loris header cut off after (s):", cut)
info = json.loads(req("GET", "/v1/assets/waving-cloth")[2])
print("immutable Cache-Control with a read token:", req("GET", info["file"])[1].get("cache-control"))
def decodes(): return [l for l in req("GET", "/metrics")[2].decode().splitlines() if l.startswith("pmcodec_decode_requests_total")][0].split()[-1]
d0 = decodes(); req("HEAD", "/v1/assets/waving-cloth/mesh?frame=7&triangles=333"); print("decodes run by one HEAD /mesh:", int(decodes()) - int(d0))
st, h, b = req("GET", "/v1/" + "a" * 60000); print("error body bytes for a 60 KB URL:", len(b))
st, h, b = req("POST", "/v1/assets?id=x&fps=1e-30", b"glTF", {"Authorization": "Bearer t", "Content-Type": "model/gltf-binary"}); print("fps=1e-30:", st)
st, h, b = req("POST", "/v1/assets?id=y&fps=1000", b"glTF", {"Authorization": "Bearer t", "Content-Type": "model/gltf-binary"}); print("fps=1000:", st)
st, h, b = req("DELETE", "/v1/jobs/0123456789abcdef0123456789abcdef", None, {"Authorization": "Bearer t"}); print("DELETE /v1/jobs/{id}:", st, b[:80])
print("X-Content-Type-Options:", h.get("x-content-type-options"))
p.terminate(); p.wait()
cfg = os.path.join(assets, "c.toml"); open(cfg, "w").write('[auth]\nwrite_token = ""\n')
q = subprocess.Popen([bin_, "-q", "serve", "--listen", f"127.0.0.1:{port}", "--config", cfg, "--no-viewer"], stderr=subprocess.PIPE)
try:
    q.wait(5); print("write_token = \"\":", "refused:", q.stderr.read().decode().strip()[:160])
except subprocess.TimeoutExpired:
    print("write_token = \"\": accepted (server running)"); q.terminate()
