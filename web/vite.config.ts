import { defineConfig } from "vite";
import { fileURLToPath } from "node:url";

// The server serves the built bundle at `/`; during development, vite proxies the API to it.
export default defineConfig({
  server: { proxy: { "/v1": "http://127.0.0.1:8080" } },
  // The viewer and the example import the package by its name, as an app would.
  resolve: { alias: { "pmcodec-three": fileURLToPath(new URL("./src/player/index.ts", import.meta.url)) } },
  worker: { format: "es" },
  // Pages: the viewer, the package's example, the LOD player the glTF test harness drives, and
  // the stream-beside-its-GLB page of the appearance test (test/appearance-e2e.mjs).
  build: { outDir: "dist", emptyOutDir: true, sourcemap: true, rollupOptions: { input: { main: "index.html", example: "example.html", lod: "lod.html", compare: "compare.html" } } },
});
