// A bounded byte-range cache over one immutable URL, filled by HTTP range requests only.
//
// The player asks for whole chunks (the container's index says where each one is), some frames
// ahead of the playhead; this module turns a list of wanted chunks into as few requests as it
// can: adjacent chunks make one range, and disjoint ranges (a banded file keeps each group's
// chunks together, proto/container.md "Index", so a frame's chunks lie in one span per group)
// go in one multi-range request, up to MAX_RANGES a request. Ranges wanted in the same tick
// (concurrent reads) share requests too. It never asks twice for bytes it holds or is already
// waiting for, and forgets the least recently used spans past its memory limit. So a looping
// animation is fetched once, as long as it fits.

/** Bytes of the resource from `start`. */
export interface Part { start: number; bytes: Uint8Array }

/**
 * Fetches byte ranges [start, end) of the resource, in one request where the source can (ends
 * past the resource's length are cut there); resolves with parts that hold some or all of them
 * (a part may hold more than was asked: a host that sent the whole file, or merged ranges) and
 * the resource's length. Ranges the parts lack are asked for again, one a request.
 */
export type FetchRanges = (ranges: [number, number][]) => Promise<{ parts: Part[]; total: number }>;

/** The most a host that ignores Range may send (the whole file, kept as one span). */
export const MAX_WHOLE_FILE = 256 << 20;

/** The default memory limit of a cache: 64 MiB of container bytes. */
export const DEFAULT_CACHE_BYTES = 64 << 20;

/**
 * Most ranges in one request: as the Rust client's MAX_RANGES_PER_REQUEST, below the server's
 * default limit (64, proto/http.md "Range requests") past which it answers with the whole file.
 */
export const MAX_RANGES = 16;

interface Span { start: number; bytes: Uint8Array; used: number }
/** A range on its way: `head` the held span it continues (it was cut to start where that ends). */
interface Pending { start: number; end: number; head?: Span; done: Promise<void>; settle: (e?: unknown) => void }

export class RangeCache {
  private spans: Span[] = [];
  private pending: Pending[] = [];
  /** Ranges wanted this tick, not yet asked for. */
  private queued: Pending[] = [];
  private held = 0;
  private clock = 0;
  /** Ranges a request: 1 once a host answered several with fewer. */
  private perRequest = MAX_RANGES;
  /** Bytes received (data, not multipart framing) and requests made, over the cache's life. */
  fetched = 0;
  requests = 0;
  /** Ranges asked for (after merging adjacent ones), over the cache's life. */
  ranges = 0;
  /** The resource's length, from the first answer (NaN before). */
  total = NaN;

  constructor(private readonly fetchRanges: FetchRanges, readonly limit = DEFAULT_CACHE_BYTES) {}

  /** Bytes held now (at most `limit`, plus the span being added when one span is larger). */
  get size(): number { return this.held; }

  private find(start: number, end: number): Span | undefined {
    for (const s of this.spans) if (s.start <= start && end <= s.start + s.bytes.length) return s;
    return undefined;
  }

  /** Whether [start, end) is held or on its way. */
  has(start: number, end: number): boolean {
    return this.find(start, end) !== undefined || this.pending.some((p) => p.start <= start && end <= p.end);
  }

  /**
   * Makes sure every range of `wanted` (pairs [start, end), any order) is held: asks for what is
   * neither held nor on its way, with the ranges other calls of this tick want, in as few
   * requests as MAX_RANGES allows.
   */
  async ensure(wanted: [number, number][]): Promise<void> {
    const waits: Promise<void>[] = [];
    for (const [start, e] of wanted) {
      let s = start;
      if (e <= s || this.find(s, e)) continue;
      // A range that begins inside a held span (the first read of a file, which ends wherever
      // its length falls, mid-chunk) asks only for the rest, and the reply is joined to that
      // span, so that the range reads from one span and no byte is fetched twice.
      const head = this.spans.find((x) => x.start < s && s < x.start + x.bytes.length);
      if (head) s = head.start + head.bytes.length;
      const p = this.pending.find((x) => x.start <= s && e <= x.end);
      if (p) { waits.push(p.done); continue; }
      let settle: (e?: unknown) => void = () => {};
      const done = new Promise<void>((ok, fail) => { settle = (err) => (err === undefined ? ok() : fail(err)); });
      const entry: Pending = { start: s, end: e, head, done, settle };
      this.pending.push(entry);
      if (this.queued.push(entry) === 1) queueMicrotask(() => this.flush());
      waits.push(done);
    }
    await Promise.all(waits);
  }

  /** Asks for the queued ranges: adjacent ones merged, up to `perRequest` ranges a request. */
  private flush(): void {
    const q = this.queued.sort((a, b) => a.start - b.start);
    this.queued = [];
    const runs: Pending[][] = [];
    let end = -1;
    for (const p of q) {
      // Only adjacent or overlapping ranges share a range: a gap may hold bytes this cache
      // already has, and fetching them again would break "each byte once".
      if (runs.length > 0 && p.start <= end) runs[runs.length - 1].push(p);
      else runs.push([p]);
      end = Math.max(end, p.end);
    }
    for (let i = 0; i < runs.length; i += this.perRequest) void this.request(runs.slice(i, i + this.perRequest));
  }

  private async request(runs: Pending[][]): Promise<void> {
    const asked = runs.map((r): [number, number] => [r[0].start, Math.max(...r.map((p) => p.end))]);
    const entries = runs.flat();
    const finish = (p: Pending, err?: unknown) => {
      this.pending = this.pending.filter((x) => x !== p);
      p.settle(err);
    };
    let answer: Awaited<ReturnType<FetchRanges>>;
    try {
      answer = await this.fetchRanges(asked);
    } catch (e) {
      for (const p of entries) finish(p, e);
      return;
    }
    this.requests++;
    this.ranges += asked.length;
    if (Number.isNaN(this.total)) this.total = answer.total;
    const total = answer.total;
    for (const part of answer.parts) {
      this.fetched += part.bytes.length;
      this.place(part, entries);
    }
    // Covered: within one part (ranges past the resource's end are cut there).
    const covered = (p: Pending) => answer.parts.some((x) => x.start <= p.start && Math.min(p.end, total) <= x.start + x.bytes.length);
    const missed = entries.filter((p) => !covered(p));
    for (const p of entries) if (covered(p)) finish(p);
    if (missed.length === 0) return;
    if (asked.length === 1) {
      const err = new Error(`bytes ${asked[0][0]}-${asked[0][1] - 1} missing from the answer`);
      for (const p of missed) finish(p, err);
      return;
    }
    // A host that answers several ranges with one (RFC 9110 lets it): one a request from now on.
    this.perRequest = 1;
    for (const p of missed) if (this.queued.push(p) === 1) queueMicrotask(() => this.flush());
  }

  /** Holds a part, joined to the span a range of `entries` continues when it starts there. */
  private place(part: Part, entries: Pending[]): void {
    const head = entries.find((p) => p.head && p.start === part.start)?.head;
    if (head && this.spans.includes(head) && head.start + head.bytes.length === part.start) {
      const joined = new Uint8Array(head.bytes.length + part.bytes.length);
      joined.set(head.bytes);
      joined.set(part.bytes, head.bytes.length);
      this.spans.splice(this.spans.indexOf(head), 1);
      this.held -= head.bytes.length;
      this.add({ start: head.start, bytes: joined, used: ++this.clock });
    } else {
      this.add({ start: part.start, bytes: part.bytes, used: ++this.clock });
    }
  }

  /** Bytes [start, start + len), fetched first if they are not held. */
  async read(start: number, len: number): Promise<Uint8Array> {
    const end = start + len;
    let s = this.find(start, end);
    if (!s) {
      await this.ensure([[start, end]]);
      s = this.find(start, end);
      // Evicted between arrival and now (a limit smaller than one frame's span): fetch again.
      if (!s) {
        const r = await this.fetchRanges([[start, end]]);
        const p = r.parts.find((x) => x.start <= start && end <= x.start + x.bytes.length);
        if (!p) throw new Error(`bytes ${start}-${end - 1} missing from the answer`);
        return p.bytes.subarray(start - p.start, end - p.start);
      }
    }
    s.used = ++this.clock;
    return s.bytes.subarray(start - s.start, end - s.start);
  }

  private add(span: Span): void {
    this.spans.push(span);
    this.held += span.bytes.length;
    // Least recently used first, but never the span just added.
    while (this.held > this.limit && this.spans.length > 1) {
      let worst = 0;
      for (let i = 1; i < this.spans.length - 1; i++) if (this.spans[i].used < this.spans[worst].used) worst = i;
      this.held -= this.spans[worst].bytes.length;
      this.spans.splice(worst, 1);
    }
  }
}

/** Bytes a multipart part may add to its data (delimiter line, headers), for bounding answers. */
const PART_FRAMING = 512;

/** A part of a multipart/byteranges body: where its bytes are in the resource, and its total. */
export interface RangePart extends Part { total: number }

/** `bytes a-b/len` (a Content-Range value; len may be `*`): [a, b + 1) and len (NaN for `*`). */
function contentRange(v: string | null): { start: number; end: number; total: number } | null {
  const m = /^\s*bytes\s+(\d+)-(\d+)\/(\d+|\*)\s*$/i.exec(v ?? "");
  if (!m) return null;
  const start = Number(m[1]), end = Number(m[2]) + 1, total = m[3] === "*" ? NaN : Number(m[3]);
  return end > start && !(end > total) ? { start, end, total } : null;
}

/**
 * The parts of a multipart/byteranges body (RFC 9110 section 14.6), read by each part's
 * Content-Range length rather than by searching the data for the boundary; after each part's
 * data the next delimiter must follow at once, so a Content-Range that misstates its part's
 * length is refused. Errors say what is wrong; the caller names the URL.
 */
export function parseMultipart(body: Uint8Array, boundary: string): RangePart[] {
  const enc = new TextEncoder(), dec = new TextDecoder();
  const delim = enc.encode(`--${boundary}`);
  const at = (i: number, needle: Uint8Array) => i + needle.length <= body.length && needle.every((b, k) => body[i + k] === b);
  const search = (from: number, needle: Uint8Array, most: number) => {
    for (let i = from; i + needle.length <= Math.min(body.length, from + most + needle.length); i++) if (at(i, needle)) return i;
    return -1;
  };
  if (boundary.length === 0 || boundary.length > 70) throw new Error(`multipart/byteranges: a boundary of ${boundary.length} characters`);
  // A preamble before the first delimiter is allowed, but not a long one.
  let i = search(0, delim, PART_FRAMING);
  if (i < 0) throw new Error("multipart/byteranges: no boundary");
  const parts: RangePart[] = [];
  const crlf2 = enc.encode("\r\n\r\n"), next = enc.encode(`\r\n--${boundary}`);
  for (;;) {
    i += delim.length;
    if (body[i] === 0x2d && body[i + 1] === 0x2d) return parts;
    const headEnd = search(i, crlf2, PART_FRAMING);
    if (headEnd < 0) throw new Error(`multipart/byteranges: part ${parts.length + 1} has no end of headers`);
    const head = dec.decode(body.subarray(i, headEnd)).split("\r\n");
    const cr = head.map((l) => /^\s*content-range\s*:(.*)$/i.exec(l)).find((m) => m !== null);
    const r = contentRange(cr ? cr[1] : null);
    if (!r) throw new Error(`multipart/byteranges: part ${parts.length + 1} has no valid Content-Range`);
    const start = headEnd + 4, stop = start + (r.end - r.start);
    if (stop > body.length) throw new Error(`multipart/byteranges: part bytes ${r.start}-${r.end - 1} is cut short (${body.length - start} bytes left)`);
    if (!at(stop, next)) throw new Error(`multipart/byteranges: part bytes ${r.start}-${r.end - 1} is not followed by the boundary (its Content-Range misstates its length)`);
    parts.push({ start: r.start, bytes: body.subarray(start, stop), total: r.total });
    i = stop + 2;
  }
}

/** Reads a response's body, refusing (and cancelling) one longer than `most` bytes. */
async function readBounded(r: Response, most: number, tooLong: (n: number) => string): Promise<Uint8Array> {
  const declared = Number(r.headers.get("Content-Length") ?? NaN);
  if (declared > most) {
    await r.body?.cancel();
    throw new Error(tooLong(declared));
  }
  if (!r.body) return new Uint8Array(await r.arrayBuffer());
  const reader = r.body.getReader(), chunks: Uint8Array[] = [];
  let n = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    n += value.length;
    if (n > most) {
      await reader.cancel();
      throw new Error(tooLong(n));
    }
    chunks.push(value);
  }
  const out = new Uint8Array(n);
  let o = 0;
  for (const c of chunks) { out.set(c, o); o += c.length; }
  return out;
}

/**
 * Range requests against a URL with `fetch`, several ranges a request (`Range: bytes=a-b,c-d`).
 * The answer may be 206 with one range (the host merged them, or sent the first only), 206
 * multipart/byteranges, or 200: a host that ignores Range sent the whole file, which is kept
 * whole (up to MAX_WHOLE_FILE), so it is fetched once all the same. Answers are bounded before
 * they are read; errors name the URL.
 */
export function httpRanges(url: string, init?: RequestInit): FetchRanges {
  return async (ranges) => {
    if (ranges.length === 0) return { parts: [], total: NaN };
    const set = ranges.map(([s, e]) => `${s}-${e - 1}`).join(",");
    const headers = new Headers(init?.headers);
    headers.set("Range", `bytes=${set}`);
    const r = await fetch(url, { ...init, headers });
    if (r.status !== 206 && r.status !== 200) throw new Error(`${url}: HTTP ${r.status} for bytes ${set}`);
    const lo = Math.min(...ranges.map((x) => x[0])), hi = Math.max(...ranges.map((x) => x[1]));
    const wanted = ranges.reduce((a, [s, e]) => a + e - s, 0);
    const what = ranges.length === 1 ? `a range of ${hi - lo}` : `${ranges.length} ranges of ${wanted} bytes`;
    if (r.status === 200) {
      const body = await readBounded(r, MAX_WHOLE_FILE, (n) => `${url}: the host ignores range requests and the file has ${n} bytes (at most ${MAX_WHOLE_FILE} are read whole)`);
      if (body.length < lo) throw new Error(`${url}: the file has ${body.length} bytes, the range starts at ${lo}`);
      return { parts: [{ start: 0, bytes: body }], total: body.length };
    }
    const type = r.headers.get("Content-Type") ?? "";
    let parts: RangePart[];
    if (/^\s*multipart\/byteranges/i.test(type)) {
      const b = /;\s*boundary\s*=\s*"?([^";]+)"?/i.exec(type);
      if (!b) { await r.body?.cancel(); throw new Error(`${url}: multipart/byteranges without a boundary`); }
      // Parts within the span asked for, each with its headers.
      const body = await readBounded(r, hi - lo + PART_FRAMING * (ranges.length + 1), (n) => `${url}: ${n} bytes for ${what}`);
      try { parts = parseMultipart(body, b[1].trim()); } catch (e) { throw new Error(`${url}: ${e instanceof Error ? e.message : e}`); }
    } else {
      const cr = contentRange(r.headers.get("Content-Range"));
      // One range: the one asked, or several merged into one span (no more than the span asked).
      const body = await readBounded(r, hi - lo, (n) => `${url}: ${n} bytes for ${what}`);
      if (!cr) throw new Error(`${url}: 206 without a valid Content-Range (${r.headers.get("Content-Range")})`);
      if (cr.end - cr.start !== body.length) throw new Error(`${url}: Content-Range of ${cr.end - cr.start} bytes, body of ${body.length}`);
      parts = [{ start: cr.start, bytes: body, total: cr.total }];
    }
    const total = parts.find((p) => !Number.isNaN(p.total))?.total ?? NaN;
    for (const p of parts) {
      const end = p.start + p.bytes.length;
      if (!Number.isNaN(p.total) && p.total !== total) throw new Error(`${url}: parts give the file's length as ${total} and ${p.total}`);
      if (p.start < lo || end > hi) throw new Error(`${url}: part bytes ${p.start}-${end - 1} lies outside the ranges asked (${set})`);
    }
    const cut = (e: number) => (Number.isNaN(total) ? e : Math.min(e, total));
    if (!ranges.some(([s, e]) => parts.some((p) => p.start <= s && cut(e) <= p.start + p.bytes.length))) throw new Error(`${url}: the answer holds none of the ranges asked (${set})`);
    return { parts: parts.map((p) => ({ start: p.start, bytes: p.bytes })), total };
  };
}
