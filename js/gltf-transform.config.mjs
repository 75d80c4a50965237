// glTF Transform CLI configuration that carries Strata's displacement layer:
//   npx gltf-transform COMMAND in.glb out.glb --config gltf-transform.config.mjs
// (run inside js/ after `npm install`, so that the CLI and this extension
// share one @gltf-transform/core).  Every extension the CLI knows stays
// registered; STRATA_layered_displacement is added to them.
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { StrataLayeredDisplacement } from './src/gltf-transform-extension.mjs';

export default { extensions: [...ALL_EXTENSIONS, StrataLayeredDisplacement] };
