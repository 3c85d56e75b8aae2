// The player's worker: fetching, decoding and cutting, off the page's main thread. It decodes
// the frame the page shows and, while playing, a few after it; results go back by transfer.

import { Session } from "./session.js";
import { httpRanges } from "./ranges.js";
import type { ColourMode, FramePayload, FromWorker, Source, ToWorker } from "./protocol.js";

/** Decoded frames kept ready ahead of the playhead while playing (a tenth of a second at 30 fps). */
const DECODE_AHEAD = 3;

let session: Session | null = null;
let frames = 0;
let playhead = 0;
let playing = false;
let seq = 0;
/** The last frame sent (for the current seq), and whether the budget moved since. */
let sent = -1;
let recut = false;
let running = false;
/** Whether the coarse frame of the last jump was tried. */
let coarseTried = false;
/** Budget and colour mode as last asked for (they may come before the container is open). */
let budget: number | null = null;
let colour: ColourMode = "authored";
/** Whether the stream's materials and images were sent (once, when "authored" is first asked for). */
let looksSent = false;

const post = (m: FromWorker, transfer: Transferable[] = []) => (self as unknown as Worker).postMessage(m, transfer);

async function containerUrl(source: Source, headers: Record<string, string> | undefined): Promise<{ url: string; trianglesPerLevel?: number[] }> {
  if ("url" in source) return { url: new URL(source.url, self.location.href).href };
  const base = new URL(source.server.endsWith("/") ? source.server : source.server + "/", self.location.href);
  const infoUrl = new URL(`v1/assets/${encodeURIComponent(source.asset)}`, base);
  const r = await fetch(infoUrl, { headers });
  if (!r.ok) throw new Error(`asset ${source.asset}: HTTP ${r.status} from ${infoUrl.href}`);
  const info = (await r.json()) as { file?: unknown; triangles_per_level?: unknown };
  if (typeof info.file !== "string") throw new Error(`asset ${source.asset}: the server's answer names no container file`);
  const tpl = Array.isArray(info.triangles_per_level) ? info.triangles_per_level.map(Number) : undefined;
  return { url: new URL(info.file, base).href, trianglesPerLevel: tpl };
}

/**
 * Posts a frame for seek `tag`. A frame of an older seek is still posted when it carries an
 * index buffer: the session counts it as sent, and later frames refer to it by version only
 * (the page keeps it, and drops the frame itself).
 */
function send(p: FramePayload, tag = seq): void {
  // Versioned skin data (the cut's skin, offsets) reaches the page however old its seek, as
  // index buffers do: later frames build on it.
  // (The session keeps no reference to what it puts in a payload: the buffers are transferred.)
  const k = p.skin;
  if (tag !== seq && !p.indices && !(k && (k.bind || k.offsets || k.changed))) return;
  p.seq = tag;
  const transfer: Transferable[] = [p.positions.buffer, p.normals.buffer];
  if (k) for (const a of [k.bind, k.joints, k.weights, k.normals, k.palette, k.offsets, k.changed, k.values, k.startBind, k.startOffsets]) if (a) transfer.push(a.buffer);
  if (p.indices) transfer.push(p.indices.buffer);
  if (p.starts) transfer.push(p.starts.buffer);
  if (p.colours) transfer.push(p.colours.buffer);
  for (const a of [p.uvs, p.uv1, p.uvStarts, p.uv1Starts]) if (a) transfer.push(a.buffer);
  post(p, transfer);
}

/** The next frame to decode: the playhead when it is not sent yet, then a few after it while playing. */
function next(): number | null {
  if (sent < 0 || recut && !playing) return playhead;
  const ahead = (sent - playhead + frames) % frames;
  if (!playing) return sent === playhead ? null : playhead;
  // A playhead past what was sent (the page skipped ahead): start over from it.
  if (ahead > DECODE_AHEAD + 1) return playhead;
  return ahead < DECODE_AHEAD ? (sent + 1) % frames : null;
}

/** Sends the stream's materials and images, the first time "authored" is asked for. */
function sendLooks(): void {
  const s = session;
  if (!s || looksSent || !s.textured) return;
  looksSent = true;
  s.looks()
    .then((l) => { if (l) post(l, l.images.map((i) => i.bytes.buffer as ArrayBuffer)); })
    .catch((e) => post({ type: "error", message: e instanceof Error ? e.message : String(e) }));
}

async function pump(): Promise<void> {
  if (running || !session) return;
  running = true;
  try {
    for (let f = next(); f !== null && session; f = next()) {
      const s = session, mine = seq;
      if (recut && !playing && f === sent) {
        recut = false;
        const p = s.recut();
        if (p) { send(p); continue; }
      }
      recut = false;
      if (sent < 0 && !coarseTried) {
        // A jump: a coarse cut first, then the budget's.
        coarseTried = true;
        const q = await s.coarse(f);
        if (q) send(q, mine);
        if (mine !== seq) continue;
      }
      const p = await s.frame(f);
      if (mine !== seq) { send(p, mine); continue; } // a seek came in meanwhile
      sent = f;
      send(p);
    }
  } catch (e) {
    post({ type: "error", message: e instanceof Error ? e.message : String(e) });
  } finally {
    running = false;
  }
}

self.onmessage = (ev: MessageEvent<ToWorker>) => {
  const m = ev.data;
  switch (m.type) {
    case "open":
      containerUrl(m.source, m.headers)
        .then(({ url, trianglesPerLevel }) => Session.open(httpRanges(url, { headers: m.headers }), { cacheBytes: m.cacheBytes, readAhead: m.readAhead, trianglesPerLevel, gpuSkin: m.gpuSkin }))
        .then((s) => {
          session = s;
          if (budget !== null) s.budget = budget;
          s.colour = colour;
          frames = s.container.header.frameCount;
          post({ type: "opened", info: s.info() });
          sendLooks();
          void pump();
        })
        .catch((e) => post({ type: "error", message: e instanceof Error ? e.message : String(e) }));
      break;
    case "playhead":
      playhead = m.frame;
      playing = m.playing;
      void pump();
      break;
    case "seek":
      seq = m.seq;
      playhead = m.frame;
      sent = -1;
      coarseTried = !m.coarse;
      void pump();
      break;
    case "budget":
      budget = m.triangles;
      if (session) session.budget = m.triangles;
      recut = true;
      void pump();
      break;
    case "colour":
      colour = m.mode;
      if (session) session.colour = m.mode;
      sendLooks();
      recut = true;
      void pump();
      break;
  }
};
