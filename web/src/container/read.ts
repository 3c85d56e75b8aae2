// Opening a .pmc file, as `pmcodec_container::Reader`: the preamble, header and index read and
// checked, then chunks fetched by (kind, frame, band), checked against their CRC-32 and
// decompressed. Byte access is a callback, so the same code reads a file in Node or HTTP
// ranges in a browser.

import { decompress } from "fzstd";
import { DecodeError } from "./error.js";
import {
  ChunkEntry, ChunkKind, FLAG_BANDS, FLAG_NAMES, frameOrder, groupOf, groupsFor, parseGroup, parseTable, FLAG_SPARSE, FLAG_STORED, Header, MAX_TABLE_LEN, PREAMBLE_LEN, checkTables, crc32, describe, isKeyframe, keyframeBefore,
  frontDecode, parseHeader, parseIndex, parsePreamble, readAt as kindReadAt,
} from "./format.js";
import { entryIsDerived } from "./derive.js";

/** Fetches `len` bytes at `offset`. */
export type ReadAt = (offset: number, len: number) => Promise<Uint8Array>;

export class Reader {
  /** `level`: the finest level the index entries held serve (0: all). */
  private constructor(readonly readAt: ReadAt, readonly version: number, readonly flags: number, readonly header: Header, readonly index: ChunkEntry[], readonly dataStart: number, readonly fileLen: number, readonly level = 0) {}
  /** Bytes fetched so far: preamble, header, index and chunks. */
  bytesRead = 0;

  /**
   * Opens a container. With `level`, a banded index (FLAG_BANDS) is read in part: its table and
   * the groups a client whose finest level is `level` reads (as `Reader::open_at`); the reader
   * then serves levels `level..` only (`level` past the top: the top, the coarsest). Other
   * files are read whole. The groups are asked for at once, so that a `readAt` that batches
   * concurrent reads (the player's RangeCache) fetches them in one request.
   */
  static async open(readAt: ReadAt, fileLen: number, level?: number): Promise<Reader> {
    if (fileLen < PREAMBLE_LEN) throw new DecodeError("not a .pmc file (too short)");
    const { version, flags, headerLen, indexLen, headerCrc, indexCrc, tableLen } = parsePreamble(await readAt(0, PREAMBLE_LEN));
    const dataStart = PREAMBLE_LEN + headerLen + indexLen;
    if (dataStart > fileLen || headerLen > MAX_TABLE_LEN || indexLen > MAX_TABLE_LEN) throw new DecodeError("header and index: the file ends before they do");
    if (version >= 7 && (flags & FLAG_BANDS) !== 0) {
      if (tableLen > indexLen) throw new DecodeError(`index table: ${tableLen} bytes in an index of ${indexLen}`);
      const tables = await readAt(PREAMBLE_LEN, headerLen + tableLen);
      const hb = tables.subarray(0, headerLen), tb = tables.subarray(headerLen);
      if (crc32(hb) !== headerCrc) throw new DecodeError("header: checksum mismatch");
      if (crc32(tb) !== indexCrc) throw new DecodeError("index table: checksum mismatch");
      const header = parseHeader(hb, version);
      if ((flags & FLAG_NAMES) !== 0) header.frameNames = frontDecode(header.frameNames);
      const levels = header.levelSizes.length;
      if (levels === 0) throw new DecodeError("header: inconsistent counts");
      const rows = parseTable(tb, levels);
      if (rows.reduce((a, r) => a + r.bodyLen, 0) !== indexLen - tableLen) throw new DecodeError("index table: its groups do not fill the index");
      const chunks = rows.reduce((a, r) => a + r.chunksLen, 0);
      if (chunks > fileLen - dataStart) throw new DecodeError("chunk area: the file ends before it does");
      if (chunks < fileLen - dataStart) throw new DecodeError(`${fileLen - dataStart - chunks} bytes after the end of the container`);
      // (Level 0 reads every group but the faces of the bands above it.)
      const partial = level !== undefined && level >= 0 ? Math.min(level, levels - 1) : undefined;
      const wanted = partial === undefined ? rows.map((_, g) => g) : groupsFor(levels, partial, rows[groupOf(ChunkKind.Faces, partial, levels)]?.derived ?? false);
      let bodyAt = PREAMBLE_LEN + headerLen + tableLen, chunkAt = 0, read = PREAMBLE_LEN + headerLen + tableLen;
      const reads: Promise<ChunkEntry[]>[] = [];
      for (let g = 0; g < rows.length; g++) {
        if (wanted.includes(g)) {
          const [row, at] = [rows[g], chunkAt];
          const body = row.bodyLen === 0 ? Promise.resolve(new Uint8Array(0)) : readAt(bodyAt, row.bodyLen);
          reads.push(body.then((b) => { read += b.length; return parseGroup(b, g, row, at, levels, header.frameCount); }));
        }
        bodyAt += rows[g].bodyLen;
        chunkAt += rows[g].chunksLen;
      }
      const entries = (await Promise.all(reads)).flat();
      const index = frameOrder(entries);
      checkTables(header, index, fileLen - dataStart, true);
      const r = new Reader(readAt, version, flags, header, index, dataStart, fileLen, partial ?? 0);
      r.bytesRead = read;
      return r;
    }
    const tables = await readAt(PREAMBLE_LEN, headerLen + indexLen);
    const hb = tables.subarray(0, headerLen), ib = tables.subarray(headerLen);
    if (crc32(hb) !== headerCrc) throw new DecodeError("header: checksum mismatch");
    if (crc32(ib) !== indexCrc) throw new DecodeError("index: checksum mismatch");
    const header = parseHeader(hb, version);
    if ((flags & FLAG_NAMES) !== 0) header.frameNames = frontDecode(header.frameNames);
    const index = parseIndex(ib, version, header.frameCount);
    checkTables(header, index, fileLen - dataStart);
    const r = new Reader(readAt, version, flags, header, index, dataStart, fileLen);
    r.bytesRead = dataStart;
    return r;
  }

  isKeyframe(f: number): boolean { return isKeyframe(this.header, f); }
  keyframeBefore(f: number): number { return keyframeBefore(this.header, f); }

  find(kind: ChunkKind, frame: number, band: number): ChunkEntry {
    const e = this.index.find((x) => x.kind === kind && x.frame === frame && x.band === band);
    if (!e) throw new DecodeError(`frame ${frame} band ${band} ${ChunkKind[kind]}: missing from the index`);
    return e;
  }

  /**
   * Frame `frame` band `band`'s chunk of `kind`: in a file with FLAG_SPARSE, a Delta or Corners
   * chunk left out reads as the empty payload (a single 0), a Positions chunk as zero residuals.
   */
  async chunkAt(kind: ChunkKind, frame: number, band: number): Promise<Uint8Array> {
    const sparse = (this.flags & FLAG_SPARSE) !== 0 && (kind === ChunkKind.Delta || kind === ChunkKind.Corners || kind === ChunkKind.Positions);
    // A Positions chunk left out: every residual zero (shift 0, sparse coding, no node listed).
    if (sparse && !this.index.some((x) => x.kind === kind && x.frame === frame && x.band === band)) return new Uint8Array(kind === ChunkKind.Positions ? [64, 0] : [0]);
    return this.chunk(this.find(kind, frame, band));
  }

  /**
   * Whether band `level`'s faces and corner updates are derived in the keyframe interval of
   * `frame` (its keyframe's Faces chunk is coding 2), told from the index entry alone.
   */
  derives(frame: number, level: number): boolean {
    if (level <= 0) return false;
    const k = this.keyframeBefore(frame), key = k * 64 + level;
    let d = this.derived.get(key);
    if (d === undefined) this.derived.set(key, d = this.index.some((x) => x.frame === k && x.band === level && entryIsDerived(x)));
    return d;
  }
  /** derives() by keyframe * 64 + level (levels are at most 64). */
  private readonly derived = new Map<number, boolean>();

  /**
   * Whether a client whose finest level is `level` reads chunk `e`: readAt, and where band
   * `level` is derived, the Triangles chunk and the Key and Delta chunks of the bands below it,
   * and frame 0's Key chunks below it where any interval derives it (Key coding 3).
   */
  reads(e: ChunkEntry, level: number): boolean {
    if (kindReadAt(e.kind, e.band, level)) return true;
    if (e.kind === ChunkKind.Triangles) return this.index.some((x) => x.band === level && entryIsDerived(x));
    // Frame 0's Key chunks below `level` wherever band `level` is derived at all: a later
    // keyframe's Key chunk may code its changes from frame 0's (Key coding 3).
    if (e.kind === ChunkKind.Key && e.frame === 0 && e.band < level) return this.derives(0, level) || this.index.some((x) => x.band === level && entryIsDerived(x));
    if (e.kind === ChunkKind.Key || e.kind === ChunkKind.Delta) return e.band < level && this.derives(e.frame, level);
    return false;
  }

  /** A chunk's decompressed bytes, checked against its CRC-32 and declared size. */
  async chunk(e: ChunkEntry): Promise<Uint8Array> {
    const stored = await this.readAt(this.dataStart + e.offset, e.storedLen);
    this.bytesRead += stored.length;
    if (crc32(stored) !== e.crc32) throw new DecodeError(`${describe(e)}: checksum mismatch`);
    if ((this.flags & FLAG_STORED) !== 0 && e.storedLen === e.rawLen) return stored;
    let raw: Uint8Array;
    try {
      raw = decompress(stored, new Uint8Array(e.rawLen));
    } catch (err) {
      // fzstd throws plain Errors on a frame that does not fit or does not parse.
      throw new DecodeError(`${describe(e)}: zstd: ${err instanceof Error ? err.message : String(err)}`);
    }
    if (raw.length !== e.rawLen) throw new DecodeError(`${describe(e)}: ${raw.length} bytes where the index says ${e.rawLen}`);
    return raw;
  }
}
