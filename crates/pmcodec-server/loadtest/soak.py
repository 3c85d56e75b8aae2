"""Soak helpers for run.sh (Python standard library only; loopback only).

  soak.py rss PID SECONDS OUT         sample VmRSS of PID every 10 s into OUT (seconds, KiB)
  soak.py slow BASE SECONDS N FILE    N slow clients: each reads LOD answers and 256 KiB ranges of
                                      the container FILE through a 4 KiB receive buffer, 1 KiB every
                                      20 ms, and sends every other request's head in pieces over
                                      half a second
  soak.py uploads BASE SECONDS DIR    an upload of 8 OBJ frames of DIR every 15 s (replace=true,
                                      three ids in turn), each job polled to its end
  soak.py summary OUT WARMUP [END]    RSS over time, and its trend between WARMUP and END seconds
                                      (the load's end) and over the second half of that
Each traffic mode prints one line: requests, and errors (any status other than 200/206/202, or a
socket error).
"""

import io
import json
import os
import random
import socket
import sys
import threading
import time
import urllib.parse
import zipfile


def split(base):
    u = urllib.parse.urlparse(base)
    assert u.hostname in ("127.0.0.1", "::1", "localhost"), "the load may only target loopback"
    return u.hostname, u.port


def request(host, port, method, path, headers=None, body=b"", slow_read=False, slow_write=False):
    """One HTTP/1.1 request on its own connection; returns (status, body)."""
    s = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
    if slow_read:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.settimeout(30)
    s.connect((host, port))
    try:
        head = f"{method} {path} HTTP/1.1\r\nHost: {host}:{port}\r\nConnection: close\r\n"
        for k, v in (headers or {}).items():
            head += f"{k}: {v}\r\n"
        if body:
            head += f"Content-Length: {len(body)}\r\n"
        data = (head + "\r\n").encode() + body
        if slow_write:
            # The head in five pieces over half a second.
            step = max(1, len(data) // 5)
            for i in range(0, len(data), step):
                s.sendall(data[i:i + step])
                time.sleep(0.1)
        else:
            s.sendall(data)
        chunks = []
        while True:
            chunk = s.recv(1024 if slow_read else 65536)
            if not chunk:
                break
            chunks.append(chunk)
            if slow_read:
                time.sleep(0.02)
        raw = b"".join(chunks)
    finally:
        s.close()
    head, _, rest = raw.partition(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1]) if head.startswith(b"HTTP/") else 0
    if b"transfer-encoding: chunked" in head.lower():
        out, pos = [], 0
        while True:
            line_end = rest.index(b"\r\n", pos)
            size = int(rest[pos:line_end], 16)
            if size == 0:
                break
            out.append(rest[line_end + 2:line_end + 2 + size])
            pos = line_end + 2 + size + 2
        rest = b"".join(out)
    return status, rest


def slow(base, seconds, n, file_url):
    host, port = split(base)
    deadline = time.time() + seconds
    counts = {"requests": 0, "errors": 0}
    lock = threading.Lock()

    def client(i):
        rng = random.Random(i)
        k = 0
        while time.time() < deadline:
            k += 1
            headers = {}
            if k % 3 == 0:
                # The first 256 KiB of the container, as a streaming client's range.
                path, ok, headers = file_url, 206, {"Range": "bytes=0-262143"}
            else:
                asset, frames, top = rng.choice([("horse", 48, 16000), ("cat", 10, 14410)])
                path = f"/v1/assets/{asset}/mesh?frame={rng.randrange(frames)}&triangles={rng.randint(200, top)}&format=bin"
                ok = 200
            try:
                status, _ = request(host, port, "GET", path, headers, slow_read=True, slow_write=k % 2 == 0)
                good = status == ok
            except OSError as e:
                print(f"slow client {i}: {e}", file=sys.stderr)
                good = False
            with lock:
                counts["requests"] += 1
                counts["errors"] += 0 if good else 1

    threads = [threading.Thread(target=client, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(f"slow clients ({n}): {counts['requests']} requests, {counts['errors']} errors")


def uploads(base, seconds, frames_dir):
    host, port = split(base)
    names = sorted(f for f in os.listdir(frames_dir) if f.endswith(".obj"))[:8]
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name in names:
            z.write(os.path.join(frames_dir, name), name)
    body = buf.getvalue()
    token = os.environ["PMCODEC_WRITE_TOKEN"]
    deadline = time.time() + seconds
    n = errors = 0
    while time.time() < deadline:
        start = time.time()
        asset = f"soak-{n % 3}"
        n += 1
        try:
            status, answer = request(host, port, "POST", f"/v1/assets?id={asset}&replace=true",
                                     {"Authorization": f"Bearer {token}", "Content-Type": "application/zip"}, body)
            if status != 202:
                raise OSError(f"upload answered {status}: {answer[:200]!r}")
            url = json.loads(answer)["status_url"]
            while True:
                status, answer = request(host, port, "GET", url)
                state = json.loads(answer)["state"] if status == 200 else f"status {status}"
                if state == "succeeded":
                    break
                if state not in ("queued", "running"):
                    raise OSError(f"job {url}: {state}: {answer[:200]!r}")
                time.sleep(0.5)
        except (OSError, ValueError, KeyError) as e:
            print(f"upload {n}: {e}", file=sys.stderr)
            errors += 1
        time.sleep(max(0.0, 15 - (time.time() - start)))
    print(f"uploads: {n} uploads of {len(body)} bytes ({len(names)} frames), {errors} errors")


def rss(pid, seconds, out):
    start = time.time()
    with open(out, "w") as f:
        while True:
            t = time.time() - start
            try:
                with open(f"/proc/{pid}/status") as s:
                    kib = next(int(line.split()[1]) for line in s if line.startswith("VmRSS:"))
            except (OSError, StopIteration):
                break
            f.write(f"{t:.0f}\t{kib}\n")
            f.flush()
            if t >= seconds:
                break
            time.sleep(10)


def trend(samples):
    """Least-squares slope of (seconds, MiB) samples, in MiB per minute."""
    n = len(samples)
    mt = sum(t for t, _ in samples) / n
    mm = sum(m for _, m in samples) / n
    return 60 * sum((t - mt) * (m - mm) for t, m in samples) / sum((t - mt) ** 2 for t, _ in samples)


def summary(out, warmup, end=None):
    rows = [tuple(map(float, line.split())) for line in open(out) if line.strip()]
    print("seconds  RSS MiB")
    for t, kib in rows:
        print(f"{t:7.0f}  {kib / 1024:7.1f}")
    end = end if end is not None else rows[-1][0]
    loaded = [(t, kib / 1024) for t, kib in rows if warmup <= t <= end]
    if len(loaded) < 6:
        print("too few samples after warm-up")
        return
    lo, hi = min(m for _, m in loaded), max(m for _, m in loaded)
    half = [s for s in loaded if s[0] >= (warmup + end) / 2]
    idle = [kib / 1024 for t, kib in rows if t > end]
    print(f"under load after {warmup:.0f} s: {lo:.1f}..{hi:.1f} MiB (spread {hi - lo:.1f} MiB), trend {trend(loaded):+.2f} MiB/min, "
          f"over the second half {trend(half):+.2f} MiB/min; first {loaded[0][1]:.1f}, last {loaded[-1][1]:.1f} MiB"
          + (f"; idle after the load: {idle[-1]:.1f} MiB" if idle else ""))


if __name__ == "__main__":
    mode, args = sys.argv[1], sys.argv[2:]
    if mode == "rss":
        rss(int(args[0]), float(args[1]), args[2])
    elif mode == "slow":
        slow(args[0], float(args[1]), int(args[2]), args[3])
    elif mode == "uploads":
        uploads(args[0], float(args[1]), args[2])
    elif mode == "summary":
        summary(args[0], float(args[1]), float(args[2]) if len(args) > 2 else None)
    else:
        sys.exit(__doc__)
