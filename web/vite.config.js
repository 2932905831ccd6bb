import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { defineConfig } from 'vite';

const outDir = fileURLToPath(new URL('../src/arap/static', import.meta.url));
/**
 * The browser tests' build (`npm run build:e2e`, modes `e2e` and `e2e-widget`): the same page and widget with the
 * test hook (src/hook.js, `window.__arap`) built in, into build/studio-e2e (outside the package and web/); the tests
 * serve it through the ARAP_STUDIO_CLIENT environment variable (src/arap/server/client_files.py). The normal build
 * leaves the hook out.
 */
const e2eDir = fileURLToPath(new URL('../build/studio-e2e', import.meta.url));

/**
 * The studio page served by `arap studio` (index.html and assets/).
 * @param {string} outDir
 */
const page = (outDir) => ({
  base: './',
  build: {
    outDir,
    emptyOutDir: true,
    assetsDir: 'assets',
    chunkSizeWarningLimit: 1000,
  },
  server: {
    proxy: {
      '/ws': { target: 'ws://127.0.0.1:8000', ws: true },
    },
  },
});

const PAGE_MODULE = 'virtual:arap-studio-page';

/**
 * The built studio page as one self-contained HTML string (its script and styles inlined), marked to talk to its
 * parent window (connection.js, createConnection): what the notebook widget shows in its frame.
 * @param {string} outDir
 */
function studioPage(outDir) {
  return {
    name: 'arap-studio-page',
    resolveId(id) {
      return id === PAGE_MODULE ? `\0${PAGE_MODULE}` : null;
    },
    load(id) {
      if (id !== `\0${PAGE_MODULE}`) return null;
      let html = readFileSync(`${outDir}/index.html`, 'utf8');
      const read = (ref) => readFileSync(`${outDir}/${ref.replace(/^\.\//, '')}`, 'utf8');
      html = html.replace(/<script type="module"[^>]*src="([^"]+)"[^>]*><\/script>/, (_, src) => {
        const code = read(src).replace(/<\/(script)/gi, '<\\/$1');
        return `<script>window.__ARAP_HOST__ = 'parent';</script>\n<script type="module">${code}</script>`;
      });
      html = html.replace(/<link rel="stylesheet"[^>]*href="([^"]+)"[^>]*>/, (_, href) => `<style>${read(href)}</style>`);
      if (!html.includes("__ARAP_HOST__ = 'parent'") || html.includes('./assets/')) {
        throw new Error('the studio page build (vite build) has an unexpected layout; build it first');
      }
      return `export default ${JSON.stringify(html)};`;
    },
  };
}

/**
 * `--mode widget`: the notebook widget's ES module (static/widget.js), after the page build.
 * @param {string} outDir
 */
const widget = (outDir) => ({
  plugins: [studioPage(outDir)],
  build: {
    outDir,
    emptyOutDir: false,
    copyPublicDir: false,
    chunkSizeWarningLimit: 2000,
    lib: {
      entry: fileURLToPath(new URL('./src/widget.js', import.meta.url)),
      formats: ['es'],
      fileName: () => 'widget.js',
    },
  },
});

export default defineConfig(({ mode }) => {
  const dir = mode.startsWith('e2e') ? e2eDir : outDir;
  return mode.endsWith('widget') ? widget(dir) : page(dir);
});
