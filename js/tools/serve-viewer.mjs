// Serves Strata's web viewer (js/viewer/) and, when given, a rig to open:
//   node tools/serve-viewer.mjs [RIG.glb] [--port 8080]
// then open the address it prints.  Static files only: the viewer's import
// map finds three in js/node_modules and the plugin in js/src.
import path from 'node:path';
import { serve } from './browser.mjs';

const args = process.argv.slice(2);
const portAt = args.indexOf('--port');
const port = portAt >= 0 ? Number(args[portAt + 1]) : 8080;
const rig = args.find((a, i) => !a.startsWith('--') && (portAt < 0 || i !== portAt + 1));
const folders = rig ? { '/rigs/': path.dirname(path.resolve(rig)) } : {};
const server = await serve(folders, {}, { port });
const query = rig ? `?rig=/rigs/${encodeURIComponent(path.basename(rig))}` : '';
console.log(`Strata viewer: ${server.url}/js/viewer/index.html${query}   (Ctrl-C stops)`);
