// The residual sections of the appearance chunks, as `pmcodec_container::appearance::codes`
// (proto/container.md, "Attributes", RESIDUALS): varints, the rANS form over the codes' bit
// lengths, or the adaptive Rice form.

import { DecodeError } from "./error.js";
import { Cursor } from "./payload.js";
import { MAX_SYMBOLS, decodeSymbols, rAnsTable } from "./rans.js";

/** A Rice quotient this large or larger is escaped (the Rust `rice::LIMIT`). */
const LIMIT = 24;
/** Running sums halve when the count reaches this (the Rust `rice::RESET`). */
const RESET = 16;
/** The largest starting parameter (the Rust `rice::LARGEST_START`). */
const LARGEST_START = 16;

/**
 * The adaptive Rice form of a RESIDUALS section (the Rust `rice::read_section`): 0; per channel
 * its starting parameter s; the length of the bits in bytes and the bits, least significant
 * first. Per channel a sum (from 2^s) and a count (from 1) of the codes before give the
 * parameter k, the smallest (at most 31) with count * 2^k >= sum; a code is its quotient in
 * unary (ones, then a zero) and its k low bits, or LIMIT ones, its bit length minus one in 5
 * bits and its bits below the highest. The sums and count halve when the count reaches RESET.
 */
function readRice(c: Cursor, raw: Uint8Array, m: number, ch: number, what: string): Uint32Array {
  c.get();
  const starts: number[] = [];
  for (let q = 0; q < ch; q++) starts.push(c.count(LARGEST_START, "Rice start parameter"));
  const len = c.get();
  if (c.pos + len > raw.length) throw new DecodeError(`${what}: ${len} bytes wanted at byte ${c.pos} of ${raw.length}`);
  const bytes = raw.subarray(c.pos, c.pos + len);
  c.pos += len;
  // Every code takes a bit at least: more codes than bits is a corrupt section.
  if (m * ch > 8 * len) throw new DecodeError(`${what}: ${m * ch} codes in ${len} bytes`);
  const codes = new Uint32Array(m * ch);
  let at = 0;
  const bit = (): number => {
    if (at >= 8 * bytes.length) throw new DecodeError(`${what}: Rice bits end early`);
    const v = (bytes[at >> 3] >> (at & 7)) & 1;
    at++;
    return v;
  };
  for (let q = 0; q < ch; q++) {
    // The sum stays below 2^53: at most RESET codes of at most 2^32 each beside 2^16.
    let sum = 2 ** starts[q], count = 1;
    for (let i = 0; i < m; i++) {
      let k = 0;
      while (k < 31 && count * 2 ** k < sum) k++;
      let quotient = 0;
      while (quotient < LIMIT && bit() === 1) quotient++;
      let z: number;
      if (quotient < LIMIT) {
        let low = 0;
        for (let x = 0; x < k; x++) low += bit() * 2 ** x;
        z = quotient * 2 ** k + low;
        if (z > 0xffffffff) throw new DecodeError(`${what}: a residual of ${k + 5} bits`);
      } else {
        let b = 0;
        for (let x = 0; x < 5; x++) b |= bit() << x;
        z = 2 ** b;
        for (let x = 0; x < b; x++) z += bit() * 2 ** x;
        if (Math.floor(z / 2 ** k) < LIMIT) throw new DecodeError(`${what}: an escaped residual that a quotient codes`);
      }
      codes[q * m + i] = z;
      sum += z;
      count++;
      if (count === RESET) { sum = Math.floor(sum / 2); count = Math.floor(count / 2); }
    }
  }
  if (Math.ceil(at / 8) !== bytes.length) throw new DecodeError(`${what}: ${bytes.length} Rice bytes where the codes take ${Math.ceil(at / 8)}`);
  return codes;
}

/**
 * `m * ch` residual codes (zigzag, channel after channel) as varints or, with `rans`, as the
 * RESIDUALS section of the Rust `put_codes`: per channel a frequency table over the codes' bit
 * lengths, the rANS stream of the lengths (code i on state i % 3 with its channel's table),
 * the mantissa bytes (b - 1 bits below the highest of a code of length b in 2..30, least
 * significant first), then escaped codes (length 31) as varints; or, where its first varint is
 * 0, the adaptive Rice form (`readRice`).
 */
export function readCodes(c: Cursor, raw: Uint8Array, m: number, ch: number, rans: boolean, what: string): Uint32Array {
  const n = m * ch, codes = new Uint32Array(n);
  if (!rans) {
    for (let i = 0; i < n; i++) codes[i] = c.get();
    return codes;
  }
  if (c.pos < raw.length && raw[c.pos] === 0) return readRice(c, raw, m, ch, what);
  const tables: Uint32Array[] = [];
  for (let k = 0; k < ch; k++) {
    const count = c.count(MAX_SYMBOLS, "symbols"), f: number[] = [];
    for (let s = 0; s < count; s++) f.push(c.get());
    tables.push(rAnsTable(f, what));
  }
  const take = (): Uint8Array => {
    const len = c.get();
    if (c.pos + len > raw.length) throw new DecodeError(`${what}: ${len} bytes wanted at byte ${c.pos} of ${raw.length}`);
    const out = raw.subarray(c.pos, c.pos + len);
    c.pos += len;
    return out;
  };
  const stream = take();
  const lengths = decodeSymbols(stream, n, (i) => tables[Math.floor(i / Math.max(m, 1))], what);
  const bits = take();
  let at = 0;
  for (let i = 0; i < n; i++) {
    const b = lengths[i];
    if (b <= 1) { codes[i] = b; continue; }
    if (b === 31) {
      const z = c.get();
      if (z < 2 ** 30) throw new DecodeError(`${what}: an escaped residual that a length codes`);
      codes[i] = z;
      continue;
    }
    if (at + b - 1 > bits.length * 8) throw new DecodeError(`${what}: mantissa bits end early`);
    let z = 2 ** (b - 1);
    for (let x = 0; x < b - 1; x++, at++) z += ((bits[at >> 3] >> (at & 7)) & 1) * 2 ** x;
    codes[i] = z;
  }
  if (Math.ceil(at / 8) !== bits.length) throw new DecodeError(`${what}: mantissa bytes left over`);
  return codes;
}

