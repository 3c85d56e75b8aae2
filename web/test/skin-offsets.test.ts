// The skinned fast path (DecoderOptions.skinOffsets): a decoder that keeps per-node offsets from
// the skinned position instead of positions must give the bit-exact positions back, and a float
// linear blend skinning of the bind positions plus those offsets (what the player's vertex
// shader draws) must land within one position quantum of them, at every frame and level.
import { test } from "node:test";
import { pmcodecBin, repoRoot, scratchDir } from "./paths.js";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { Decoder, Reader } from "../src/container/index.js";

const root = repoRoot();
const bin = pmcodecBin(root);
const dir = scratchDir("pmc-skin-");

async function open(pmc: string): Promise<Reader> {
  const bytes = new Uint8Array(readFileSync(pmc));
  return Reader.open(async (o, n) => bytes.slice(o, o + n), bytes.length);
}

/**
 * Decodes frames `frames` of `pmc` at level `level` both ways and checks them; returns the
 * largest float-skinning error in quanta and the frames the fast decoder skinned on the CPU.
 */
async function check(pmc: string, level: number, frames: number[]): Promise<{ worst: number; exact: number; skins: number }> {
  const c = await open(pmc), h = c.header;
  assert.ok(h.skin, `${pmc}: a skinned stream`);
  const exact = new Decoder(c, level), fast = new Decoder(c, level, { skinOffsets: true });
  let worst = 0;
  for (const f of frames) {
    await exact.seek(f);
    await fast.seek(f);
    assert.ok(fast.holdsOffsets);
    const want = exact.positions();
    assert.deepEqual(fast.positions(), want, `frame ${f} level ${level}: positions from offsets are the exact ones`);
    const skin = fast.skinAttributes()!, palette = fast.paletteMatrices(), offsets = fast.offsets();
    const extent = Math.max(...h.bboxMax.map((v, a) => Math.abs(v) + Math.abs(h.bboxMin[a])));
    // One quantum, plus float32 rounding of the matrices, of the positions and of the sum.
    const tolerance = h.step + 4e-6 * extent;
    for (let g = exact.replay.offsets[level]; g < exact.replay.nodeCount; g++) {
      const b = skin.bind.subarray(3 * g, 3 * g + 3);
      for (let a = 0; a < 3; a++) {
        let p = offsets[3 * g + a];
        for (let k = 0; k < 4; k++) {
          const w = skin.weights[4 * g + k];
          if (w === 0) continue;
          const m = 16 * skin.joints[4 * g + k];
          p += w * (palette[m + a] * b[0] + palette[m + 4 + a] * b[1] + palette[m + 8 + a] * b[2] + palette[m + 12 + a]);
        }
        const e = Math.abs(p - want[3 * g + a]);
        assert.ok(e <= tolerance, `frame ${f} level ${level} node ${g} axis ${a}: float skinning ${p} vs ${want[3 * g + a]}, ${e / h.step} quanta`);
        worst = Math.max(worst, e / h.step);
      }
    }
  }
  return { worst, exact: fast.exactFrames, skins: fast.cpuSkins };
}

const range = (n: number, step = 1) => Array.from({ length: Math.ceil(n / step) }, (_, i) => i * step);

test("generated skinned tubes (Pose and Palette chunks): offsets plus float skinning match the exact decoder at every frame and level", async () => {
  for (const file of ["crates/pmcodec-container/tests/corpus/valid-skinned-tube-k4.pmc", "crates/pmcodec-container/tests/compat/v6-skinned-palette-tube-k4.pmc"]) {
    const pmc = join(root, file), c = await open(pmc);
    for (const level of [0, 1, c.header.levelSizes.length - 1]) {
      const { worst, skins } = await check(pmc, level, range(c.header.frameCount));
      assert.ok(worst < 1, `${file} level ${level}: ${worst} quanta`);
      // Every band of these files is skinned in every frame: no node is skinned on the CPU.
      assert.equal(skins, 0, `${file} level ${level}: nodes skinned on the CPU`);
    }
  }
});

test("RobotExpressive and Fox: offsets plus float skinning match the exact decoder at every frame, for several levels, and after a seek", async () => {
  for (const name of ["RobotExpressive", "Fox"]) {
    const glb = join(root, `../shared/data/gltf/${name}.glb`);
    if (!existsSync(glb)) throw new Error(`${glb} is absent: this test reads the real models in ../shared/data beside the repository`);
    const pmc = join(dir, `${name}.pmc`);
    execFileSync(bin, ["encode", "-q", glb, "-o", pmc, "--keyframe-interval", "8", "--quant-bits", "12"]);
    const c = await open(pmc), n = c.header.frameCount, top = c.header.levelSizes.length - 1;
    // Every frame at a coarse level; a span of frames over two keyframes at full resolution.
    const coarse = await check(pmc, Math.max(0, top - 2), range(n));
    const { worst, exact, skins } = await check(pmc, 0, range(Math.min(n, 20)));
    const nodes = c.header.levelSizes.reduce((a, b) => a + b, 0);
    console.log(`${name}: ${n} frames; worst ${worst.toFixed(3)} quanta at level 0, ${coarse.worst.toFixed(3)} at level ${Math.max(0, top - 2)}; ` +
      `frames with a band not skinned: ${exact} of 20 at level 0 (${(skins / 20 / nodes).toFixed(3)} CPU skinnings per node per frame), ${coarse.exact} of ${n} at level ${Math.max(0, top - 2)}`);
    // A jump backwards and forwards: the offsets restart at the keyframe.
    await check(pmc, 1, [Math.floor(n / 2), 3, n - 1]);
    assert.ok(worst < 1, `${name}: ${worst} quanta`);
  }
});
