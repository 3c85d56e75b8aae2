// A bounded byte-range cache over one immutable URL, filled by HTTP range requests only.
//
// The player asks for whole chunks (the container's index says where each one is), a frame or a
// few ahead of the playhead; this module turns a list of wanted chunks into as few requests as
// the file's layout allows (adjacent chunks share one request, proto/container.md "Layout": what
// a client needs of a frame is one contiguous span), never asks twice for bytes it holds or is
// already waiting for, and forgets the least recently used spans past its memory limit. So a
// looping animation is fetched once, as long as it fits.

/**
 * Fetches bytes [start, end) of the resource; resolves with them and the resource's length.
 * `at`: where the bytes start when that is not `start` (a host that sent the whole file).
 */
export type FetchRange = (start: number, end: number) => Promise<{ bytes: Uint8Array; total: number; at?: number }>;

/** The most a host that ignores Range may send (the whole file, kept as one span). */
export const MAX_WHOLE_FILE = 256 << 20;

/** The default memory limit of a cache: 64 MiB of container bytes. */
export const DEFAULT_CACHE_BYTES = 64 << 20;

interface Span { start: number; bytes: Uint8Array; used: number }

export class RangeCache {
  private spans: Span[] = [];
  private pending: { start: number; end: number; done: Promise<void> }[] = [];
  private held = 0;
  private clock = 0;
  /** Bytes received and requests made, over the cache's life. */
  fetched = 0;
  requests = 0;

  constructor(private readonly fetchRange: FetchRange, readonly limit = DEFAULT_CACHE_BYTES) {}

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
   * Makes sure every range of `wanted` (pairs [start, end), any order) is held: requests what is
   * neither held nor on its way, one request per run of adjacent ranges, all at once.
   */
  async ensure(wanted: [number, number][]): Promise<void> {
    const waits: Promise<void>[] = [];
    const missing: [number, number][] = [];
    // A range that begins inside a held span (the first read of a file, which ends wherever its
    // length falls, mid-chunk) asks only for the rest, and the reply is joined to that span, so
    // that the range reads from one span and no byte is fetched twice.
    const heads = new Map<number, Span>();
    for (const [start, e] of wanted) {
      let s = start;
      if (e <= s || this.find(s, e)) continue;
      const head = this.spans.find((x) => x.start < s && s < x.start + x.bytes.length);
      if (head) {
        s = head.start + head.bytes.length;
        heads.set(s, head);
      }
      const p = this.pending.find((x) => x.start <= s && e <= x.end);
      if (p) waits.push(p.done);
      else missing.push([s, e]);
    }
    missing.sort((a, b) => a[0] - b[0]);
    const runs: [number, number][] = [];
    for (const [s, e] of missing) {
      const last = runs[runs.length - 1];
      // Only adjacent or overlapping ranges share a request: a gap may hold bytes this cache
      // already has, and fetching them again would break "each byte once".
      if (last && s <= last[1]) last[1] = Math.max(last[1], e);
      else runs.push([s, e]);
    }
    for (const [s, e] of runs) {
      const entry = { start: s, end: e, done: Promise.resolve() };
      entry.done = this.fetchRange(s, e).then(
        ({ bytes, at }) => {
          this.requests++;
          this.fetched += bytes.length;
          const start = at ?? s, head = heads.get(start);
          if (head && this.spans.includes(head) && head.start + head.bytes.length === start) {
            const joined = new Uint8Array(head.bytes.length + bytes.length);
            joined.set(head.bytes);
            joined.set(bytes, head.bytes.length);
            this.spans.splice(this.spans.indexOf(head), 1);
            this.held -= head.bytes.length;
            this.add({ start: head.start, bytes: joined, used: ++this.clock });
          } else {
            this.add({ start, bytes, used: ++this.clock });
          }
        },
      ).finally(() => { this.pending = this.pending.filter((x) => x !== entry); });
      this.pending.push(entry);
      waits.push(entry.done);
    }
    await Promise.all(waits);
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
        const r = await this.fetchRange(start, end), at = r.at ?? start;
        return r.bytes.subarray(start - at, end - at);
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

/**
 * Range requests against a URL with `fetch`. A host that answers 200 (it ignores Range) sent the
 * whole file: it is kept whole (up to MAX_WHOLE_FILE), so it is fetched once all the same.
 */
export function httpRange(url: string, init?: RequestInit): FetchRange {
  return async (start, end) => {
    const headers = new Headers(init?.headers);
    headers.set("Range", `bytes=${start}-${end - 1}`);
    const r = await fetch(url, { ...init, headers });
    if (r.status !== 206 && r.status !== 200) throw new Error(`${url}: HTTP ${r.status} for bytes ${start}-${end - 1}`);
    // Bound what is read before reading it.
    const declared = Number(r.headers.get("Content-Length") ?? NaN);
    const most = r.status === 200 ? MAX_WHOLE_FILE : end - start;
    if (declared > most) {
      await r.body?.cancel();
      throw new Error(r.status === 200 ? `${url}: the host ignores range requests and the file has ${declared} bytes (at most ${MAX_WHOLE_FILE} are read whole)` : `${url}: ${declared} bytes for a range of ${end - start}`);
    }
    const body = new Uint8Array(await r.arrayBuffer());
    if (r.status === 200) {
      if (body.length < end) throw new Error(`${url}: the file has ${body.length} bytes, the range ends at ${end}`);
      return { bytes: body, total: body.length, at: 0 };
    }
    // Content-Range: bytes a-b/total.
    const m = /\/(\d+)\s*$/.exec(r.headers.get("Content-Range") ?? "");
    const total = m ? Number(m[1]) : NaN;
    if (body.length !== Math.min(end, total || end) - start) throw new Error(`${url}: asked for ${end - start} bytes at ${start}, got ${body.length}`);
    return { bytes: body, total };
  };
}
