// Bundle the page into python/mimicrete/teleop/static/ (served by `mimicrete teleop`).
// ESM with code splitting: emulate.js (iwer + @iwer/devui) becomes its own chunks, fetched only
// when the page runs with ?emulate=quest3. Everything is local: nothing is loaded from a CDN.
import * as esbuild from 'esbuild';
import { copyFile, mkdir, rm } from 'node:fs/promises';
import { fileURLToPath } from 'node:url';
import path from 'node:path';

const here = path.dirname(fileURLToPath(import.meta.url));
const out = path.resolve(here, '../python/mimicrete/teleop/static');

await rm(out, { recursive: true, force: true });
await mkdir(out, { recursive: true });
const result = await esbuild.build({
  entryPoints: [path.join(here, 'src/main.js')],
  outdir: out,
  bundle: true,
  splitting: true,
  format: 'esm',
  target: ['chrome120', 'firefox121', 'safari17'],
  minify: true,
  sourcemap: 'linked',
  chunkNames: 'chunks/[name]-[hash]',
  define: { 'process.env.NODE_ENV': '"production"' }, // React (devui) production build
  legalComments: 'linked',
  metafile: true,
  logLevel: 'warning',
});
await copyFile(path.join(here, 'index.html'), path.join(out, 'index.html'));
for (const [file, info] of Object.entries(result.metafile.outputs)) {
  if (!file.endsWith('.map')) console.log(`${(info.bytes / 1024).toFixed(0).padStart(6)} KiB  ${path.relative(out, file)}`);
}
