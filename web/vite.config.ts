import { defineConfig } from "vite";

// The server serves the built bundle at `/`; during development, vite proxies the API to it.
export default defineConfig({
  server: { proxy: { "/v1": "http://127.0.0.1:8080" } },
  // Two pages: the viewer, and the LOD player the glTF test harness drives (lod.html).
  build: { outDir: "dist", emptyOutDir: true, sourcemap: true, rollupOptions: { input: { main: "index.html", lod: "lod.html" } } },
});
