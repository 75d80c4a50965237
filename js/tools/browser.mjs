// Headless Chromium (Debian's chromium, driven by puppeteer-core) and a
// static server for pages that import three, Strata's plugin and files a
// test made: what the browser tests, the viewer smoke test and the browser
// bench share.
//
//   const server = await serve({ '/work/': workDir });   // js/ is served at /js/
//   const browser = await launchChromium();
//   const tab = await openPage(browser, server.url + '/js/test/page.html');
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

export const jsDir = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
export const root = path.resolve(jsDir, '..');

const types = {
  '.js': 'text/javascript', '.mjs': 'text/javascript', '.html': 'text/html', '.css': 'text/css',
  '.glb': 'model/gltf-binary', '.gltf': 'model/gltf+json', '.wasm': 'application/wasm', '.json': 'application/json',
  '.png': 'image/png', '.jpg': 'image/jpeg',
};

/// The import map a page needs: three (bare specifier), its addons and the
/// plugin's package name, resolved inside js/.
export const importMap = JSON.stringify({
  imports: {
    three: '/js/node_modules/three/build/three.module.js',
    'three/addons/': '/js/node_modules/three/examples/jsm/',
    'strata-layered/three': '/js/src/three-plugin.mjs',
    'strata-layered/runtime': '/js/src/runtime.mjs',
  },
});

/// Serves js/ at /js/ and each { prefix: folder } given; `pages` maps a
/// path to HTML text; port 0 takes a free one.  Resolves to { url, close, bytesServed }.
export async function serve(folders = {}, pages = {}, { port = 0 } = {}) {
  const mounts = { '/js/': jsDir, ...folders };
  let bytesServed = 0;
  const server = http.createServer((req, res) => {
    const url = decodeURIComponent(req.url.split('?')[0]);
    if (url === '/favicon.ico') {
      res.writeHead(204);
      res.end();
      return;
    }
    if (pages[url] !== undefined) {
      res.writeHead(200, { 'content-type': 'text/html' });
      res.end(pages[url]);
      return;
    }
    const prefix = Object.keys(mounts).find((p) => url.startsWith(p));
    const file = prefix ? path.join(mounts[prefix], url.slice(prefix.length)) : null;
    if (!file || !file.startsWith(path.resolve(mounts[prefix])) || !fs.existsSync(file) || fs.statSync(file).isDirectory()) {
      res.writeHead(404);
      res.end();
      return;
    }
    bytesServed += fs.statSync(file).size;
    res.writeHead(200, { 'content-type': types[path.extname(file)] || 'application/octet-stream' });
    fs.createReadStream(file).pipe(res);
  });
  await new Promise((resolve, reject) => {
    server.once('error', reject);
    server.listen(port, '127.0.0.1', resolve);
  });
  return {
    url: `http://127.0.0.1:${server.address().port}`,
    close: () => new Promise((resolve) => server.close(resolve)),
    get bytesServed() { return bytesServed; },
    resetBytes() { bytesServed = 0; },
  };
}

export function chromiumPath() {
  const found = ['/usr/bin/chromium', '/usr/bin/chromium-browser', '/usr/bin/google-chrome'].find((p) => fs.existsSync(p));
  if (!found) throw new Error('no Chromium (cmake/install-deps.sh installs Debian\'s chromium)');
  return found;
}

/// Headless Chromium with WebGL2 on SwiftShader (no GPU on CI machines).
export function launchChromium() {
  return puppeteer.launch({
    executablePath: chromiumPath(), headless: true,
    args: ['--no-sandbox', '--disable-dev-shm-usage', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--ignore-gpu-blocklist'],
  });
}

/// A tab at `url`, failing on any page error or console error.
export async function openPage(browser, url, { viewport = { width: 960, height: 720 } } = {}) {
  const tab = await browser.newPage();
  const errors = [];
  tab.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
  tab.on('console', (m) => { if (m.type() === 'error') errors.push(`console error: ${m.text()}`); });
  await tab.setViewport(viewport);
  await tab.goto(url);
  tab.errors = errors;
  return tab;
}
