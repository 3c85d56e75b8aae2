// Texture coordinates predicted from bind positions (the Rust `appearance::project`;
// proto/container.md, "Attributes, band 0 with derived entries", bind positions): a corner
// placed against a known edge as its position lies against the edge in 3D (Isenburg &
// Snoeyink, "Compressing texture coordinates with selective linear predictions", 2003). In
// BigInt, so every value is the Rust decoder's, bit for bit.

/** Coordinate differences at or beyond this fall back to the rule without positions. */
const LIMIT = 1n << 28n;

/** The floor of the square root of `x` >= 0 (Newton's method from a power of two above it). */
export function isqrt(x: bigint): bigint {
  if (x < 2n) return x < 0n ? 0n : x;
  let r = 1n << BigInt(Math.ceil(x.toString(2).length / 2));
  for (;;) {
    const next = (r + x / r) / 2n;
    if (next >= r) return r;
    r = next;
  }
}

/** floor(a / b) for b > 0 (BigInt division truncates toward zero). */
function floorDiv(a: bigint, b: bigint): bigint {
  const q = a / b;
  return a % b < 0n ? q - 1n : q;
}

/**
 * The prediction of corner x's `[u, v]` from the edge (a, b): bind positions `bind[3 * node]`
 * of a, b and x, the edge's texture coordinates `ua`, `ub`, and the chart's `side` (+1 or -1);
 * null for a degenerate edge or coordinate differences of 2^28 or more.
 */
export function predictUv(bind: BigInt64Array, a: number, b: number, x: number, ua: [number, number], ub: [number, number], side: number): [number, number] | null {
  const n = [0, 1, 2].map((k) => bind[3 * b + k] - bind[3 * a + k]), w = [0, 1, 2].map((k) => bind[3 * x + k] - bind[3 * a + k]);
  for (const v of [...n, ...w]) if (v >= LIMIT || -v >= LIMIT) return null;
  const nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
  if (nn === 0n) return null;
  const dot = n[0] * w[0] + n[1] * w[1] + n[2] * w[2], ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  const cross = nn * ww - dot * dot, h = isqrt(cross < 0n ? 0n : cross) * BigInt(Math.sign(side));
  const d0 = BigInt(ub[0]) - BigInt(ua[0]), d1 = BigInt(ub[1]) - BigInt(ua[1]);
  const round = (y: bigint): number => Number(BigInt.asIntN(32, floorDiv(2n * y + nn, 2n * nn)));
  return [(ua[0] + round(dot * d0 - h * d1)) | 0, (ua[1] + round(dot * d1 + h * d0)) | 0];
}

/** The sign of the cross product of b - a and c - a (texture coordinates as 32-bit integers). */
export function orientation(a: [number, number], b: [number, number], c: [number, number]): number {
  const x1 = BigInt(b[0]) - BigInt(a[0]), y1 = BigInt(b[1]) - BigInt(a[1]), x2 = BigInt(c[0]) - BigInt(a[0]), y2 = BigInt(c[1]) - BigInt(a[1]);
  const z = x1 * y2 - y1 * x2;
  return z > 0n ? 1 : z < 0n ? -1 : 0;
}

/**
 * The order band 0's traversal visits the triangles in with bind positions (the Rust
 * `breadth_first`): breadth first within each chart over shared edges, from each triangle not
 * yet reached in input order.
 */
export function breadthFirst(triangles: Uint32Array, chartOf: Uint32Array): Uint32Array {
  const count = triangles.length / 3;
  let n = 0;
  for (const v of triangles) n = Math.max(n, v + 1);
  // The triangles at each vertex, ascending, each once.
  const start = new Uint32Array(n + 1);
  const distinct = (j: number, i: number): boolean => (i < 1 || triangles[3 * j + i] !== triangles[3 * j]) && (i < 2 || triangles[3 * j + 2] !== triangles[3 * j + 1]);
  for (let j = 0; j < count; j++) for (let i = 0; i < 3; i++) if (distinct(j, i)) start[triangles[3 * j + i] + 1]++;
  for (let v = 0; v < n; v++) start[v + 1] += start[v];
  const at = start.slice(), incident = new Uint32Array(start[n]);
  for (let j = 0; j < count; j++) for (let i = 0; i < 3; i++) if (distinct(j, i)) incident[at[triangles[3 * j + i]]++] = j;
  const reached = new Uint8Array(count), order = new Uint32Array(count), queue = new Uint32Array(count);
  let out = 0;
  for (let s = 0; s < count; s++) {
    if (reached[s]) continue;
    reached[s] = 1;
    let head = 0, tail = 0;
    queue[tail++] = s;
    while (head < tail) {
      const i = queue[head++];
      order[out++] = i;
      for (let k = 0; k < 3; k++) {
        const a = triangles[3 * i + k], b = triangles[3 * i + ((k + 1) % 3)];
        for (let x = start[a]; x < start[a + 1]; x++) {
          const j = incident[x];
          if (!reached[j] && chartOf[j] === chartOf[i] && (triangles[3 * j] === b || triangles[3 * j + 1] === b || triangles[3 * j + 2] === b)) {
            reached[j] = 1;
            queue[tail++] = j;
          }
        }
      }
    }
  }
  return order;
}
