// glTF Transform's own CLI, kept running: the ecosystem matrix sends it
// command lines and it runs each one through the CLI's program, as
// `gltf-transform ARGS...` would, without starting Node again per file
// (about 0.7 s of CPU each, for some 200 cells).
//
//   fork('gltf-transform-worker.mjs', ['--config', FILE])  (or no arguments)
//   child.send({ id, argv })  ->  { id, code, out }
//
// The CLI reads --config from the process's own arguments when it loads, so
// one worker serves one config.  Commands run one at a time, in order, each
// parsed by the argument parser the CLI registered its commands with (the
// CLI's own run() takes no arguments and does not wait).
import { program as parser } from '@donmccurdy/caporal';
import { program, programReady } from '@gltf-transform/cli';

program.disableGlobalOption('--silent');
await programReady;

let queue = Promise.resolve();
process.on('message', ({ id, argv }) => {
  queue = queue.then(async () => {
    try {
      await parser.run(argv);
      process.send({ id, code: 0, out: '' });
    } catch (e) {
      process.send({ id, code: 1, out: `error: ${e && e.message ? e.message : String(e)}` });
    }
  });
});
process.send({ ready: true });
