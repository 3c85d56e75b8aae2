// Multi-range requests of the player's byte cache (web/src/player/ranges.ts): disjoint ranges
// batched up to MAX_RANGES a request, hosts that answer several ranges with one or with the
// whole file, and multipart/byteranges answers parsed by their Content-Range, hostile ones
// refused with errors that name the URL.
import { test } from "node:test";
import assert from "node:assert/strict";
import { createServer, type IncomingMessage, type ServerResponse } from "node:http";
import { httpRanges, MAX_RANGES, parseMultipart, RangeCache, type FetchRanges } from "../src/player/ranges.js";

const body = Buffer.from(Uint8Array.from({ length: 5000 }, (_, i) => (i * 13 + 5) & 0xff));

/** `bytes=a-b,c-d` as [a, b + 1) pairs (a test server's parser: closed ranges only). */
function asked(req: IncomingMessage): [number, number][] {
  const v = /^bytes=(.*)$/.exec(req.headers.range ?? "");
  return v ? v[1].split(",").map((r) => r.split("-").map(Number)).map(([a, b]): [number, number] => [a, Math.min(b, body.length - 1) + 1]) : [];
}

/** A multipart/byteranges body as pmcodec's server writes it (crates/pmcodec-server, ranges.rs). */
function multipart(ranges: [number, number][], boundary: string, lie = (r: [number, number]) => r): Buffer {
  const out: Buffer[] = [];
  for (const r of ranges) {
    const [a, b] = lie(r);
    out.push(Buffer.from(`\r\n--${boundary}\r\nContent-Type: application/octet-stream\r\ncontent-range: bytes ${a}-${b - 1}/${body.length}\r\n\r\n`), body.subarray(r[0], r[1]));
  }
  out.push(Buffer.from(`\r\n--${boundary}--\r\n`));
  return Buffer.concat(out);
}

const routes: Record<string, (req: IncomingMessage, res: ServerResponse) => void> = {
  // Several ranges: multipart (boundary quoted); one: a plain 206.
  "/multi": (req, res) => {
    const r = asked(req);
    if (r.length === 1) {
      res.writeHead(206, { "Content-Range": `bytes ${r[0][0]}-${r[0][1] - 1}/${body.length}` });
      res.end(body.subarray(r[0][0], r[0][1]));
      return;
    }
    const m = multipart(r, "3d6b6a416f9b5");
    res.writeHead(206, { "Content-Type": 'multipart/byteranges; boundary="3d6b6a416f9b5"', "Content-Length": m.length });
    res.end(m);
  },
  // Only ever the first range asked.
  "/first": (req, res) => {
    const [[a, b]] = asked(req);
    res.writeHead(206, { "Content-Range": `bytes ${a}-${b - 1}/${body.length}` });
    res.end(body.subarray(a, b));
  },
  // Several ranges merged into one span.
  "/merged": (req, res) => {
    const r = asked(req), a = Math.min(...r.map((x) => x[0])), b = Math.max(...r.map((x) => x[1]));
    res.writeHead(206, { "Content-Range": `bytes ${a}-${b - 1}/${body.length}` });
    res.end(body.subarray(a, b));
  },
  "/whole": (_req, res) => { res.writeHead(200); res.end(body); },
  // A part whose Content-Range says one byte more than its data.
  "/wrong-range": (req, res) => {
    const m = multipart(asked(req), "b", ([a, b]) => [a, b + 1]);
    res.writeHead(206, { "Content-Type": "multipart/byteranges; boundary=b" });
    res.end(m);
  },
  // The whole file as the parts of a few bytes, without a Content-Length: bounded while read.
  "/too-much": (req, res) => {
    res.writeHead(206, { "Content-Type": "multipart/byteranges; boundary=b" });
    res.write(multipart(asked(req), "b").subarray(0, 60));
    res.end(Buffer.alloc(1 << 20));
  },
  "/too-much-declared": (_req, res) => {
    res.writeHead(206, { "Content-Type": "multipart/byteranges; boundary=b", "Content-Length": 1 << 20 });
    res.end(Buffer.alloc(1 << 20));
  },
  "/no-boundary-param": (req, res) => {
    res.writeHead(206, { "Content-Type": "multipart/byteranges" });
    res.end(multipart(asked(req), "b"));
  },
  "/no-boundary": (req, res) => {
    res.writeHead(206, { "Content-Type": "multipart/byteranges; boundary=elsewhere" });
    res.end(multipart(asked(req), "b"));
  },
  // A part outside the ranges asked.
  "/outside": (req, res) => {
    const m = multipart(asked(req).map(([a, b]): [number, number] => [a + 1000, b + 1000]), "b");
    res.writeHead(206, { "Content-Type": "multipart/byteranges; boundary=b" });
    res.end(m);
  },
};

async function withServer(run: (base: string, hits: Map<string, number>) => Promise<void>): Promise<void> {
  const hits = new Map<string, number>();
  const server = createServer((req, res) => {
    hits.set(req.url!, (hits.get(req.url!) ?? 0) + 1);
    const route = routes[req.url ?? ""];
    if (route) route(req, res); else { res.writeHead(404); res.end(); }
  });
  await new Promise<void>((r) => server.listen(0, "127.0.0.1", r));
  try {
    await run(`http://127.0.0.1:${(server.address() as { port: number }).port}`, hits);
  } finally {
    server.close();
  }
}

/** `n` disjoint ranges of 10 bytes, 30 apart. */
const disjoint = (n: number) => Array.from({ length: n }, (_, i): [number, number] => [30 * i + 7, 30 * i + 17]);

async function holds(c: RangeCache, ranges: [number, number][]): Promise<void> {
  for (const [s, e] of ranges) assert.deepEqual(Array.from(await c.read(s, e - s)), Array.from(body.subarray(s, e)), `bytes ${s}-${e - 1}`);
}

test("range cache: disjoint ranges go MAX_RANGES a request, and reads of one tick share requests", async () => {
  const calls: number[] = [];
  const fetch: FetchRanges = async (ranges) => {
    calls.push(ranges.length);
    return { parts: ranges.map(([s, e]) => ({ start: s, bytes: body.slice(s, e) })), total: body.length };
  };
  const c = new RangeCache(fetch);
  const want = disjoint(2 * MAX_RANGES + 3);
  await c.ensure(want);
  assert.deepEqual(calls, [MAX_RANGES, MAX_RANGES, 3]);
  assert.equal(c.fetched, 10 * want.length);
  assert.equal(c.ranges, want.length);
  // Concurrent reads (a reader reading several index groups at once): one request.
  await Promise.all([c.read(4000, 5), c.read(4100, 5), c.read(4200, 5)]);
  assert.deepEqual(calls, [MAX_RANGES, MAX_RANGES, 3, 3]);
  await holds(c, want);
  assert.equal(calls.length, 4, "held ranges were asked for again");
});

test("httpRanges: a multipart answer split by its parts' Content-Range; one range, a merged span and the whole file work too", async () => {
  await withServer(async (base, hits) => {
    const want = disjoint(20);
    for (const path of ["/multi", "/merged", "/whole"]) {
      const c = new RangeCache(httpRanges(base + path));
      await c.ensure(want);
      await holds(c, want);
      assert.equal(c.total, body.length);
      assert.equal(hits.get(path), 2, `${path}: requests`);
    }
    // One range: a plain 206.
    const one = await httpRanges(base + "/multi")([[100, 110]]);
    assert.deepEqual([one.parts.length, one.parts[0].start, one.total], [1, 100, body.length]);
  });
});

test("httpRanges: a host that answers several ranges with the first only gets one range a request after that", async () => {
  await withServer(async (base, hits) => {
    const c = new RangeCache(httpRanges(base + "/first"));
    const want = disjoint(5);
    await c.ensure(want);
    await holds(c, want);
    // The batch, then the four it lacked one by one.
    assert.equal(hits.get("/first"), 5);
    await c.ensure([[3000, 3010], [3100, 3110]]);
    assert.equal(hits.get("/first"), 7);
    await holds(c, [[3000, 3010], [3100, 3110]]);
  });
});

test("httpRanges: hostile answers are refused with the URL: a wrong Content-Range, too many bytes, no boundary, parts not asked for, HTTP errors", async () => {
  await withServer(async (base) => {
    const two: [number, number][] = [[10, 20], [40, 50]];
    const refuses = (path: string, why: RegExp) => assert.rejects(httpRanges(base + path)(two), (e: Error) => {
      assert.ok(e.message.startsWith(base + path + ":"), `the URL first: ${e.message}`);
      assert.match(e.message, why);
      return true;
    });
    await refuses("/wrong-range", /not followed by the boundary/);
    await refuses("/too-much", /bytes for 2 ranges of 20 bytes/);
    await refuses("/too-much-declared", /1048576 bytes for 2 ranges/);
    await refuses("/no-boundary-param", /without a boundary/);
    await refuses("/no-boundary", /no boundary/);
    await refuses("/outside", /outside the ranges asked/);
    await refuses("/missing", /HTTP 404 for bytes 10-19,40-49/);
    // Through the cache: the error reaches every reader.
    await assert.rejects(new RangeCache(httpRanges(base + "/wrong-range")).ensure(two), /wrong-range: multipart/);
  });
});

test("parseMultipart: parts by their lengths (a boundary inside the data does not cut a part), a cut-short part, a missing Content-Range", () => {
  const enc = (s: string) => new TextEncoder().encode(s);
  const ok = enc("preamble\r\n--xyz\r\nContent-Range: bytes 2-6/10\r\n\r\n--xyz\r\n--xyz\r\nCONTENT-RANGE:bytes 9-9/10\r\n\r\nq\r\n--xyz--\r\n");
  const parts = parseMultipart(ok, "xyz");
  assert.deepEqual(parts.map((p) => [p.start, new TextDecoder().decode(p.bytes), p.total]), [[2, "--xyz", 10], [9, "q", 10]]);
  assert.throws(() => parseMultipart(ok.subarray(0, 50), "xyz"), /cut short/);
  assert.throws(() => parseMultipart(enc("\r\n--xyz\r\nContent-Type: a/b\r\n\r\nabc\r\n--xyz--"), "xyz"), /no valid Content-Range/);
  assert.throws(() => parseMultipart(enc("\r\n--xyz\r\nContent-Range: bytes 5-2/10\r\n\r\nabc\r\n--xyz--"), "xyz"), /no valid Content-Range/);
  assert.throws(() => parseMultipart(enc("\r\n--xyz\r\nContent-Range: bytes 0-1/10"), "xyz"), /no end of headers/);
});
