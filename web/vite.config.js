import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { defineConfig } from 'vite';

const outDir = fileURLToPath(new URL('../src/arap/static', import.meta.url));

/** The normal build: the studio page served by `arap studio` (index.html and assets/). */
const page = {
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
};

const PAGE_MODULE = 'virtual:arap-studio-page';

/**
 * The built studio page as one self-contained HTML string (its script and styles inlined), marked to talk to its
 * parent window (connection.js, createConnection): what the notebook widget shows in its frame.
 */
function studioPage() {
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

/** `--mode widget`: the notebook widget's ES module (static/widget.js), after the page build. */
const widget = {
  plugins: [studioPage()],
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
};

export default defineConfig(({ mode }) => (mode === 'widget' ? widget : page));
