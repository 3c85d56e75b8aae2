// GPU skinning of skinned streams (issue 17): the player's mesh becomes a three.js SkinnedMesh
// whose skeleton's bone matrices are the stream's palette, frame by frame, so three.js's own
// skinning chunks pose positions and normals with every material (textures, vertex colours,
// wireframe, flat shading). The stream adds what three.js lacks: each vertex's offset from its
// skinned position (the decoder's skinned offsets, proto/container.md "Skinning"), added after
// skinning, and the geomorph of Houle and Poulin ("Simplification and Real-time Smooth
// Transitions of Articulated Meshes", 2001), which blends the bind positions (before skinning)
// and the offsets (after) from where each vertex starts to its own.

import * as THREE from "three";

/** Per-vertex attributes the patched shader reads, besides three.js's skinIndex and skinWeight. */
export const OFFSET = "pmcOffset", START_BIND = "pmcStartBind", START_OFFSET = "pmcStartOffset";

/**
 * A skeleton of `joints` bones that draws `palette` (16 floats per entry, column-major) as its
 * bone matrices: three.js calls `update` once per rendered frame, which here copies the palette
 * the player set last instead of deriving matrices from bones (there is no bone hierarchy: the
 * palette already holds each joint's skinning transform, bind space to the stream's space).
 */
export class PaletteSkeleton extends THREE.Skeleton {
  palette: Float32Array;
  private changed = true;

  constructor(joints: number) {
    // Bones at the origin: their inverses are the identity, so the bind matrix is too.
    super(Array.from({ length: Math.max(1, joints) }, () => new THREE.Bone()));
    this.palette = new Float32Array(16 * this.bones.length);
    for (let e = 0; e < this.bones.length; e++) this.palette.set([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], 16 * e);
  }

  /** Takes a frame's palette (entries beyond the skeleton's are ignored). */
  setPalette(p: Float32Array): void {
    this.palette.set(p.subarray(0, this.palette.length));
    this.changed = true;
  }

  override update(): void {
    if (!this.changed) return;
    // computeBoneTexture replaces boneMatrices with a larger array: copy into whichever it is now.
    this.boneMatrices?.set(this.palette);
    if (this.boneTexture) this.boneTexture.needsUpdate = true;
    // Until the texture exists (first draw), keep copying.
    this.changed = this.boneTexture === null;
  }
}

/**
 * The skinned mesh the player draws a GPU-skinned stream with: bind matrix the identity, so
 * three.js's skinning is sum_k w_k M_k b (its "attached" bind mode with an identity bind).
 */
export function paletteMesh(geometry: THREE.BufferGeometry, material: THREE.Material | THREE.Material[], skeleton: PaletteSkeleton): THREE.SkinnedMesh {
  const mesh = new THREE.SkinnedMesh(geometry, material);
  mesh.bind(skeleton, new THREE.Matrix4());
  // Three.js would compute a skinned mesh's bounds by skinning every vertex on the CPU: the
  // whole animation's box (the geometry's) holds in every frame.
  if (geometry.boundingBox) mesh.boundingBox = geometry.boundingBox.clone();
  if (geometry.boundingSphere) mesh.boundingSphere = geometry.boundingSphere.clone();
  return mesh;
}

const patched = new WeakSet<THREE.Material>();

/**
 * Adds the offsets and the geomorph to a material's vertex shader where it skins (USE_SKINNING;
 * the same material on an unskinned mesh draws as before). `morph` is the geomorph's blend
 * (smoothstep of its progress; 1: none), shared by every material of a player.
 */
export function patchMaterial(m: THREE.Material, morph: { value: number }): void {
  if (patched.has(m)) return;
  patched.add(m);
  const before = m.onBeforeCompile.bind(m), key = m.customProgramCacheKey.bind(m);
  m.onBeforeCompile = (shader, renderer) => {
    before(shader, renderer);
    shader.uniforms.pmcMorph = morph;
    shader.vertexShader = shader.vertexShader
      .replace("#include <common>", `#include <common>
#ifdef USE_SKINNING
attribute vec3 ${OFFSET};
attribute vec3 ${START_BIND};
attribute vec3 ${START_OFFSET};
uniform float pmcMorph;
#endif`)
      .replace("#include <begin_vertex>", `#include <begin_vertex>
#ifdef USE_SKINNING
transformed = mix(${START_BIND}, transformed, pmcMorph);
#endif`)
      .replace("#include <skinning_vertex>", `#include <skinning_vertex>
#ifdef USE_SKINNING
transformed += mix(${START_OFFSET}, ${OFFSET}, pmcMorph);
#endif`);
  };
  m.customProgramCacheKey = () => `${key()}|pmc-skin-offsets`;
  m.needsUpdate = true;
}
