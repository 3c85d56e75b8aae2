#!/usr/bin/env bash
# Makes the compressed fixtures of tests/compressed_gltf.rs from the shared Fox:
#   (cd tests && npm ci) && bash crates/pmcodec-mesh/tests/compressed/make-fixtures.sh
# The Fox's texture is dropped first (the fixtures test geometry, skin and animation, and stay
# small), then gltfpack 1.3.0 (npm) compresses it with its defaults plus -cc: quantized
# positions, UVs and normals, the octahedral filter on normals, the quaternion filter on
# rotations, and the index codec. One fixture per extension name (EXT_ and KHR_).
# tests/draco-fixture.mjs (glTF Transform + draco3dgltf) makes the Draco one: edgebreaker, with a
# COLOR_0 added so every attribute the extension maps is there.
# gltfpack and the Draco encoder are deterministic, so the same inputs give the same bytes.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
fox="$here/../../../../../shared/data/gltf/Fox.glb"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 - "$fox" "$tmp/fox-untextured.glb" <<'PY'
import json, struct, sys
data = open(sys.argv[1], 'rb').read()
json_len = struct.unpack_from('<I', data, 12)[0]
doc = json.loads(data[20:20 + json_len])
bin_chunk = data[20 + json_len + 8:]
for key in ('images', 'textures', 'samplers'):
    doc.pop(key, None)
for m in doc.get('materials', []):
    m.get('pbrMetallicRoughness', {}).pop('baseColorTexture', None)
text = json.dumps(doc, separators=(',', ':')).encode()
text += b' ' * (-len(text) % 4)
bin_chunk += b'\0' * (-len(bin_chunk) % 4)
out = struct.pack('<4sII', b'glTF', 2, 12 + 8 + len(text) + 8 + len(bin_chunk))
out += struct.pack('<I4s', len(text), b'JSON') + text + struct.pack('<I4s', len(bin_chunk), b'BIN\0') + bin_chunk
open(sys.argv[2], 'wb').write(out)
PY
npx -y gltfpack@1.3.0 -i "$tmp/fox-untextured.glb" -o "$here/fox-meshopt-ext.glb" -cc -ce ext
npx -y gltfpack@1.3.0 -i "$tmp/fox-untextured.glb" -o "$here/fox-meshopt-khr.glb" -cc -ce khr
node "$here/../../../../tests/draco-fixture.mjs" "$tmp/fox-untextured.glb" "$here/fox-draco.glb"
