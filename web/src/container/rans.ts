// rANS decoding of position residuals (proto/container.md, "Positions, band j"), as
// `pmcodec_container::rans`: range asymmetric numeral systems after J. Duda, "Asymmetric
// numeral systems: entropy coding combining speed of Huffman coding with compression rate of
// arithmetic coding" (2013), byte-wise renormalisation and interleaved states as in F. Giesen,
// "Interleaved entropy coders" (2014). 12-bit frequencies, states in [2^23, 2^31), three
// interleaved states, one per axis. Every product freq * (x >>> 12) is below 2^31, so plain JS
// numbers and 32-bit operators compute it exactly.

import { DecodeError } from "./error.js";

/** Frequencies add up to M = 2^12; states stay in [L, 2^31). */
export const M = 4096, L = 1 << 23;
/** Symbols per table; the last one escapes to a varint after the stream. */
export const MAX_SYMBOLS = 32, ESCAPE = 31;

/**
 * The decoding table of one axis: per slot of [0, M), its symbol's frequency (bits 0..12), the
 * slot's offset in the symbol's range (13..24) and the symbol (25..29).
 */
export function rAnsTable(freqs: number[], what: string): Uint32Array {
  const sum = freqs.reduce((a, b) => a + b, 0);
  if (freqs.length === 0 || sum !== M) throw new DecodeError(`${what}: frequency table does not add up to 4096`);
  const t = new Uint32Array(M);
  let at = 0;
  for (let s = 0; s < freqs.length; s++) { for (let k = 0; k < freqs[s]; k++) t[at + k] = freqs[s] | (k << 13) | (s << 25); at += freqs[s]; }
  return t;
}

/**
 * Decodes `out.length` zigzagged residuals from `stream`, symbol i with table i % 3; an escaped
 * symbol's value comes from `escape` (the varints after the stream, in order). Checks that the
 * stream ends exactly where its final states say (`decodeSymbols`, the one rANS loop).
 */
export function decodeResiduals(stream: Uint8Array, tables: Uint32Array[], out: Int32Array, what: string, escape: () => number): void {
  const symbols = decodeSymbols(stream, out.length, (i) => tables[i % 3], what);
  for (let i = 0; i < out.length; i++) {
    const z = symbols[i] === ESCAPE ? escape() : symbols[i];
    out[i] = (z >>> 1) ^ -(z & 1);
  }
}

/**
 * Decodes `count` symbols from `stream`, symbol i on state i % 3 with the table `tableOf(i)`
 * (the position residuals' table changes with the state, the attribute tables' residual
 * lengths' by channel; the Rust `Decoder::get` one at a time). Checks that the stream ends exactly where its final
 * states say.
 */
export function decodeSymbols(stream: Uint8Array, count: number, tableOf: (i: number) => Uint32Array, what: string): Uint32Array {
  const len = stream.length;
  if (len < 12) throw new DecodeError(`${what}: rANS stream shorter than its states`);
  const x = [0, 0, 0];
  for (let w = 0; w < 3; w++) {
    x[w] = ((stream[4 * w] << 24) >>> 0) + (stream[4 * w + 1] << 16) + (stream[4 * w + 2] << 8) + stream[4 * w + 3];
    if (x[w] < L || x[w] >= 2 ** 31) throw new DecodeError(`${what}: rANS state out of range`);
  }
  const out = new Uint32Array(count);
  let pos = 12, overrun = false;
  for (let i = 0; i < count; i++) {
    const w = i % 3, t = tableOf(i);
    let s = x[w];
    const e = t[s & (M - 1)];
    s = (e & 0x1fff) * (s >>> 12) + ((e >>> 13) & 0xfff);
    while (s < L) {
      if (pos >= len) { overrun = true; s = L; break; }
      s = (s << 8) | stream[pos++];
    }
    x[w] = s;
    out[i] = e >>> 25;
  }
  if (overrun) throw new DecodeError(`${what}: rANS stream ends early`);
  if (pos !== len || x[0] !== L || x[1] !== L || x[2] !== L) throw new DecodeError(`${what}: rANS stream does not end where it should`);
  return out;
}
