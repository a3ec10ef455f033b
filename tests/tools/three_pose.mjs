// Load a GLB with three.js (GLTFLoader) as a web app shows it with no animation playing and print,
// as JSON on stdout, every mesh's world-space vertices: morph targets at their default
// influences and skinned meshes posed by their bones (SkinnedMesh.getVertexPosition, which
// applies the morphs and applyBoneTransform), then the mesh's matrixWorld; and, for a skinned
// mesh, the world box from SkinnedMesh.computeBoundingBox.
//
// usage: node three_pose.mjs FILE.glb
// output: {"meshes": [{"name", "skinned", "positions": [[x, y, z] per vertex],
//          "box": [[min], [max]] or null}]}
// Exit code: 0 on success, 2 on usage/IO/loading problems (one line on stderr).
import { readFile } from "node:fs/promises";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";

function parse(buffer) {
  const loader = new GLTFLoader();
  return new Promise((resolve, reject) => loader.parse(buffer, "", resolve, reject));
}

function fail(message) {
  process.stderr.write(`three_pose: ${message}\n`);
  process.exitCode = 2;
}

async function main() {
  const [path] = process.argv.slice(2);
  if (!path) {
    fail("usage: node three_pose.mjs FILE.glb");
    return;
  }
  const data = await readFile(path);
  const gltf = await parse(data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength));
  const root = gltf.scene;
  root.updateMatrixWorld(true);
  const meshes = [];
  root.traverse((o) => {
    if (!o.isMesh) return;
    if (o.isSkinnedMesh) o.skeleton.update();    // the bone matrices a render would upload
    const v = new THREE.Vector3();
    const positions = [];
    for (let i = 0; i < o.geometry.attributes.position.count; i++) {
      o.getVertexPosition(i, v);
      positions.push(v.applyMatrix4(o.matrixWorld).toArray());
    }
    let box = null;
    if (o.isSkinnedMesh) {
      o.computeBoundingBox();
      const b = o.boundingBox.clone().applyMatrix4(o.matrixWorld);
      box = [b.min.toArray(), b.max.toArray()];
    }
    meshes.push({ name: o.name, skinned: !!o.isSkinnedMesh, positions, box });
  });
  process.stdout.write(JSON.stringify({ meshes }) + "\n");
}

main().catch((e) => fail(e && e.message ? e.message : String(e)));
