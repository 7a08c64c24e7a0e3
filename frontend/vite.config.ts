/**
 * Vite build for the servodesk UI.
 *
 * The build lands inside the Python package (backend/servodesk/web/dist) so an editable
 * install and the wheel both serve it without a copy step. JSX goes through Vite's own
 * esbuild (no React plugin): the UI needs no fast-refresh machinery to be built offline.
 * The build also copies Swagger UI into dist/vendor/swagger-ui, where the backend's /docs
 * page loads it from, so the API docs work without internet access.
 */
import { copyFileSync, mkdirSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { type Plugin, defineConfig } from 'vite';

const here = dirname(fileURLToPath(import.meta.url));
const outDir = resolve(here, '../backend/servodesk/web/dist');
const backend = process.env.SERVODESK_BACKEND ?? 'http://127.0.0.1:8000';

function swaggerUi(): Plugin {
  return {
    name: 'servodesk-swagger-ui',
    apply: 'build',
    writeBundle() {
      const require = createRequire(import.meta.url);
      const src = dirname(require.resolve('swagger-ui-dist/package.json'));
      const dest = join(outDir, 'vendor', 'swagger-ui');
      mkdirSync(dest, { recursive: true });
      for (const f of ['swagger-ui-bundle.js', 'swagger-ui.css', 'LICENSE', 'NOTICE']) {
        copyFileSync(join(src, f), join(dest, f));
      }
    },
  };
}

export default defineConfig({
  base: '/',
  esbuild: { jsx: 'automatic' },
  plugins: [swaggerUi()],
  build: {
    outDir,
    emptyOutDir: true,
    target: 'es2022',
    sourcemap: false,
    chunkSizeWarningLimit: 800,
  },
  server: {
    host: '127.0.0.1',
    port: 5173,
    proxy: {
      '/api': { target: backend, ws: true, changeOrigin: false },
    },
  },
});
