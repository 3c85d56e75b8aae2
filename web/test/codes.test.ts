// The appearance chunks' residual sections (web/src/container/codes.ts) against bytes the Rust
// encoder wrote: `GOLDEN` is the constant of `appearance::codes::rice`'s tests, which assert the
// Rust `section` writes it; both decoders must read the same codes from it.

import { test } from "node:test";
import assert from "node:assert/strict";
import { Cursor, DecodeError, readCodes } from "../src/container/index.js";

const GOLDEN = Uint8Array.from([0, 4, 11, 25, 64, 200, 254, 31, 29, 224, 255, 255, 223, 2, 45, 49, 2, 32, 1, 8, 56, 208, 11, 125, 150, 7, 0, 2, 0]);
const CODES = [0, 1, 2, 3, 100, 7, 0, 5_000_000, 1, 9, 4, 4000, 4001, 3990, 0, 2];

test("an adaptive Rice section the Rust encoder wrote reads as the same codes, and a damaged one is a DecodeError", () => {
  const c = new Cursor(GOLDEN, "golden");
  assert.deepEqual(Array.from(readCodes(c, GOLDEN, 8, 2, true, "golden")), CODES);
  c.finish();
  // More codes than the section has bits: refused before any is read.
  assert.throws(() => readCodes(new Cursor(GOLDEN, "many"), GOLDEN, 1_000_000, 2, true, "many"), /codes in/);
  for (let cut = 1; cut < GOLDEN.length; cut++) {
    const b = GOLDEN.subarray(0, cut);
    assert.throws(() => readCodes(new Cursor(b, "cut"), b, 8, 2, true, "cut"), DecodeError, `cut at ${cut}`);
  }
  // A start parameter beyond 16, then every single-bit flip: an error or other codes, never
  // anything but a DecodeError.
  const big = Uint8Array.from(GOLDEN);
  big[1] = 17;
  assert.throws(() => readCodes(new Cursor(big, "big"), big, 8, 2, true, "big"), DecodeError);
  for (let at = 1; at < GOLDEN.length; at++) {
    for (let bit = 0; bit < 8; bit++) {
      const b = Uint8Array.from(GOLDEN, (x, i) => (i === at ? x ^ (1 << bit) : x));
      try { readCodes(new Cursor(b, "flip"), b, 8, 2, true, "flip"); } catch (e) { assert.ok(e instanceof DecodeError, `byte ${at} bit ${bit}: ${e}`); }
    }
  }
});
