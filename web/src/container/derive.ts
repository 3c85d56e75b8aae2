// Derived topology (proto/container.md, "Faces", coding 2), as `pmcodec_container::derive`: a
// band whose keyframe Faces chunk is the two bytes 0 2 sends neither faces nor corner updates up
// to the next keyframe; its reader walks the input triangles up the parent maps below the band
// (Kircher & Garland 2005, section 4.1: a swap below level j changes exactly the level-j
// corners of the triangles under the moved node).

import { ChunkEntry, ChunkKind } from "./format.js";
import { Swap } from "./replay.js";

/** The payload of a derived Faces chunk: a 0, then coding 2. */
export const DERIVED_FACES = [0, 2];

/** Whether a Faces payload says "derived". */
export function isDerived(raw: Uint8Array): boolean {
  return raw.length === 2 && raw[0] === 0 && raw[1] === 2;
}

/** Whether a Faces chunk's index entry is a derived one (the only Faces payload of two bytes). */
export function entryIsDerived(e: ChunkEntry): boolean {
  return e.kind === ChunkKind.Faces && e.rawLen === 2;
}

const distinct = (c: Uint32Array, i: number): boolean => c[i] !== c[i + 1] && c[i + 1] !== c[i + 2] && c[i] !== c[i + 2];

/**
 * A level-L reader's view of the levels below L in a derived interval: the parent maps of levels
 * 0..L-1 and every triangle's level-L corners (those not alive included, as the encoder keeps
 * them), so that each frame's updates are exactly those a Corners chunk would carry.
 */
export class Below {
  readonly corners: Uint32Array;

  /** `parents[i]`: the keyframe's parent map of level i < L (checked in range by readKey). */
  constructor(readonly triangles: Uint32Array, readonly parents: Uint32Array[]) {
    this.corners = new Uint32Array(triangles.length);
    for (let i = 0; i < triangles.length; i++) this.corners[i] = this.walk(triangles[i]);
  }

  private walk(v: number): number {
    for (const p of this.parents) v = p[v];
    return v;
  }

  /** The keyframe's faces: every triangle alive at L with its level-L corners, ascending. */
  faces(): { t: number; corners: [number, number, number] }[] {
    const out: { t: number; corners: [number, number, number] }[] = [];
    const c = this.corners;
    for (let t = 0; 3 * t < c.length; t++) if (distinct(c, 3 * t)) out.push({ t, corners: [c[3 * t], c[3 * t + 1], c[3 * t + 2]] });
    return out;
  }

  /**
   * Applies a frame's moves of the levels below L (checked in range by readDelta) and returns the
   * corner updates at L: the triangles whose corners changed and that were or became alive there.
   */
  apply(moves: Swap[]): { t: number; corners: [number, number, number] }[] {
    let any = false;
    for (const m of moves) {
      const p = this.parents[m.level];
      if (!p) continue;
      if (p[m.v] !== m.to) any = true;
      p[m.v] = m.to;
    }
    const out: { t: number; corners: [number, number, number] }[] = [];
    if (!any) return out;
    const c = this.corners, tris = this.triangles, now = new Uint32Array(3);
    for (let t = 0; 3 * t < c.length; t++) {
      for (let i = 0; i < 3; i++) now[i] = this.walk(tris[3 * t + i]);
      const changed = now[0] !== c[3 * t] || now[1] !== c[3 * t + 1] || now[2] !== c[3 * t + 2];
      if (changed && (distinct(now, 0) || distinct(c, 3 * t))) out.push({ t, corners: [now[0], now[1], now[2]] });
      c.set(now, 3 * t);
    }
    return out;
  }
}
