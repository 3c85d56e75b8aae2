// What the browser tests and page benchmarks share: `pmcodec serve` started on a random port
// (its output kept when asked, for tests that read its request log), a wait until it answers
// /readyz, and Debian's headless Chromium with the flags every page here runs under.
import { chromium } from "playwright-core";
import { spawn } from "node:child_process";

export const root = new URL("../..", import.meta.url).pathname;
export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/**
 * Starts `pmcodec serve --listen 127.0.0.1:PORT ...args` with PORT in [from, from + 1000).
 * With `capture`, the server's stdout and stderr (its request log) collect in `.log`.
 */
export function serve(bin, args, { from = 18000, capture = false, env = process.env } = {}) {
  const port = from + Math.floor(Math.random() * 1000);
  const server = spawn(bin, ["serve", "--listen", `127.0.0.1:${port}`, ...args], { stdio: capture ? ["ignore", "pipe", "pipe"] : "ignore", env });
  const handle = { server, base: `http://127.0.0.1:${port}`, log: "" };
  if (capture) {
    server.stdout.on("data", (d) => { handle.log += d; });
    server.stderr.on("data", (d) => { handle.log += d; });
  }
  return handle;
}

/** Waits until the server at `base` answers /readyz (it may encode samples first), at most `ms`. */
export async function ready(base, ms = 300_000) {
  const deadline = Date.now() + ms;
  for (;;) {
    try { if ((await fetch(`${base}/readyz`)).ok) return; } catch {}
    if (Date.now() > deadline) throw new Error(`server at ${base} did not start within ${ms / 1000} s`);
    await sleep(250);
  }
}

/** Headless Chromium (software rendering, no background traffic). */
export function launch() {
  return chromium.launch({
    executablePath: "/usr/bin/chromium",
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync"],
  });
}
