// A stream's materials as three.js materials (the page's side of the container's appearance
// module, container/appearance.ts, whose `Materials` it takes): glTF 2.0's metallic-roughness
// materials (the Khronos glTF 2.0 specification, section 3.9) as MeshStandardMaterial, built
// the way three.js's own GLTFLoader builds them, so a stream draws as its source GLB does in
// three.js: base colour factor and texture, metallic and roughness factors and texture,
// normal, occlusion and emissive textures with their samplers and KHR_texture_transform, alpha
// mode and cutoff, double-sided.

import * as THREE from "three";
import { RoomEnvironment } from "three/examples/jsm/environments/RoomEnvironment.js";
import type { Material, Materials, TextureRef } from "../container/appearance.js";

export type { Material, Materials, TextureRef } from "../container/appearance.js";

/** glTF's sampler enums (WebGL's) as three.js constants; absent ones take glTF's defaults. */
const FILTERS: Record<number, THREE.MagnificationTextureFilter | THREE.MinificationTextureFilter> = {
  9728: THREE.NearestFilter, 9729: THREE.LinearFilter, 9984: THREE.NearestMipmapNearestFilter,
  9985: THREE.LinearMipmapNearestFilter, 9986: THREE.NearestMipmapLinearFilter, 9987: THREE.LinearMipmapLinearFilter,
};
const WRAPS: Record<number, THREE.Wrapping> = { 33071: THREE.ClampToEdgeWrapping, 33648: THREE.MirroredRepeatWrapping, 10497: THREE.RepeatWrapping };

/** The alpha modes as the container stores them (pmcodec_mesh::appearance::AlphaMode). */
export const ALPHA_OPAQUE = 0, ALPHA_MASK = 1, ALPHA_BLEND = 2;

/** An image's encoded bytes (PNG, JPEG, ...) with its MIME type. */
export interface EncodedImage { name?: string | null; mimeType: string; bytes: Uint8Array }

export interface BuildOptions {
  /** Whether the geometry has vertex colours (COLOR_0): they multiply the base colour. */
  vertexColors?: boolean;
  /**
   * Whether the geometry has tangents. Without them three.js derives the tangent frame from
   * screen-space derivatives, whose bitangent points the other way, and GLTFLoader flips the
   * normal scale's y for it; so does this (pmcodec streams carry no tangents).
   */
  tangents?: boolean;
  /**
   * Faceted shading. glTF 2.0 (section 3.7.2.1) says a primitive without normals is drawn
   * with flat normals, and GLTFLoader does so; a stream whose input had no normals (its
   * header's `normals` false) keeps the decoder's smooth normals for other uses but is drawn flat.
   */
  flatShading?: boolean;
}

/**
 * Decodes the images as GLTFLoader's ImageBitmapLoader does (no premultiplied alpha, no colour
 * space conversion, not flipped: glTF's texture origin is the top left).
 */
export async function decodeImages(images: EncodedImage[]): Promise<(ImageBitmap | null)[]> {
  return Promise.all(images.map(async (im) => {
    try {
      const blob = new Blob([im.bytes as BlobPart], { type: im.mimeType });
      return await createImageBitmap(blob, { premultiplyAlpha: "none", colorSpaceConversion: "none", imageOrientation: "from-image" });
    } catch {
      // As GLTFLoader: an image that does not decode leaves its material untextured.
      return null;
    }
  }));
}

/**
 * The textures of a stream: texture i draws image `textures[i].image` with its sampler. A
 * material's reference with a texture transform or another texture coordinate set gets its
 * own clone (see `buildMaterials`).
 */
export function buildTextures(m: Materials, images: (ImageBitmap | HTMLImageElement | HTMLCanvasElement | null)[]): (THREE.Texture | null)[] {
  return m.textures.map((t, i) => {
    const image = images[t.image];
    if (!image) return null;
    const tex = new THREE.Texture(image);
    tex.flipY = false;
    tex.name = m.images[t.image]?.name ?? `texture ${i}`;
    const s = t.sampler !== null ? m.samplers[t.sampler] : undefined;
    tex.magFilter = (s?.magFilter != null ? FILTERS[s.magFilter] : undefined) as THREE.MagnificationTextureFilter ?? THREE.LinearFilter;
    tex.minFilter = (s?.minFilter != null ? FILTERS[s.minFilter] : undefined) ?? THREE.LinearMipmapLinearFilter;
    tex.wrapS = (s ? WRAPS[s.wrapS] : undefined) ?? THREE.RepeatWrapping;
    tex.wrapT = (s ? WRAPS[s.wrapT] : undefined) ?? THREE.RepeatWrapping;
    tex.generateMipmaps = tex.minFilter !== THREE.NearestFilter && tex.minFilter !== THREE.LinearFilter;
    tex.needsUpdate = true;
    return tex;
  });
}

/**
 * A material's use of a texture: its own clone of the texture (sharing the image: three.js
 * uploads a Source once) with the use's colour space, coordinate set and KHR_texture_transform,
 * as GLTFLoader's assignTexture and texture transform extension make it.
 */
function use(ref: TextureRef | null, textures: (THREE.Texture | null)[], colorSpace: THREE.ColorSpace): THREE.Texture | null {
  if (!ref) return null;
  const base = textures[ref.texture];
  if (!base) return null;
  const tr = ref.transform;
  const tex = base.clone();
  tex.colorSpace = colorSpace;
  tex.channel = tr?.texCoord ?? ref.texCoord;
  if (tr) {
    tex.offset.fromArray(tr.offset);
    tex.rotation = tr.rotation;
    tex.repeat.fromArray(tr.scale);
  }
  tex.needsUpdate = true;
  return tex;
}

/**
 * The stream's materials as MeshStandardMaterial, one per container material (a mesh with
 * groups draws group g with material `groups[g].material`). `textures` from `buildTextures`.
 */
export function buildMaterials(m: Materials, textures: (THREE.Texture | null)[], options: BuildOptions = {}): THREE.MeshStandardMaterial[] {
  const list = m.materials.length > 0 ? m.materials : [defaultMaterial()];
  return list.map((d) => {
    const mat = new THREE.MeshStandardMaterial({
      color: new THREE.Color().setRGB(d.baseColorFactor[0], d.baseColorFactor[1], d.baseColorFactor[2], THREE.LinearSRGBColorSpace),
      opacity: d.baseColorFactor[3],
      metalness: d.metallicFactor,
      roughness: d.roughnessFactor,
      emissive: new THREE.Color().setRGB(d.emissiveFactor[0], d.emissiveFactor[1], d.emissiveFactor[2], THREE.LinearSRGBColorSpace),
      side: d.doubleSided ? THREE.DoubleSide : THREE.FrontSide,
      vertexColors: options.vertexColors ?? false,
      flatShading: options.flatShading ?? false,
    });
    if (d.name) mat.name = d.name;
    mat.map = use(d.baseColorTexture, textures, THREE.SRGBColorSpace);
    // glTF packs roughness in G and metalness in B of one texture; three.js reads them there.
    const mr = use(d.metallicRoughnessTexture, textures, THREE.NoColorSpace);
    mat.metalnessMap = mr;
    mat.roughnessMap = mr;
    mat.normalMap = use(d.normalTexture, textures, THREE.NoColorSpace);
    if (mat.normalMap) mat.normalScale.set(d.normalScale, options.tangents ? d.normalScale : -d.normalScale);
    mat.aoMap = use(d.occlusionTexture, textures, THREE.NoColorSpace);
    if (mat.aoMap) mat.aoMapIntensity = d.occlusionStrength;
    mat.emissiveMap = use(d.emissiveTexture, textures, THREE.SRGBColorSpace);
    if (d.alphaMode === ALPHA_BLEND) {
      mat.transparent = true;
      // three.js issue 17706, as GLTFLoader: blended surfaces do not hide what is behind them.
      mat.depthWrite = false;
    } else {
      mat.transparent = false;
      if (d.alphaMode === ALPHA_MASK) mat.alphaTest = d.alphaCutoff;
    }
    mat.needsUpdate = true;
    return mat;
  });
}

/** glTF's default material (section 3.9.6), for a stream with appearance but no materials. */
function defaultMaterial(): Material {
  return {
    name: null, baseColorFactor: [1, 1, 1, 1], baseColorTexture: null, metallicFactor: 1, roughnessFactor: 1, metallicRoughnessTexture: null,
    normalTexture: null, normalScale: 1, occlusionTexture: null, occlusionStrength: 1, emissiveTexture: null, emissiveFactor: [0, 0, 0],
    alphaMode: ALPHA_OPAQUE, alphaCutoff: 0.5, doubleSided: false,
  };
}

/**
 * An environment light for PBR materials: three.js's RoomEnvironment prefiltered by
 * PMREMGenerator (the image-based lighting of B. Karis, "Real Shading in Unreal Engine 4",
 * 2013, that MeshStandardMaterial samples); without one, metallic surfaces render black.
 * Set the result as `scene.environment`. `size`: the cube faces' size (smaller is faster to
 * make, blurrier in mirror-like materials).
 */
export function roomEnvironment(renderer: THREE.WebGLRenderer, size = 256): THREE.Texture {
  const pmrem = new THREE.PMREMGenerator(renderer);
  const env = pmrem.fromScene(new RoomEnvironment(), 0.04, 0.1, 100, { size }).texture;
  pmrem.dispose();
  return env;
}
