// Load a GLB with three.js (GLTFLoader + AnimationMixer) the way a web app would, play one clip
// and print, as JSON on stdout, the world position of every bone at the requested times.
//
// usage: node three_probe.mjs FILE.glb CLIP T0[,T1,...]
//   CLIP  : the glTF animation's name
//   Ti    : seconds into the clip
// output: {"clip", "duration", "bones": [names], "times": [...], "positions": [[[x,y,z] per bone]
//          per time], "userData": the scene's userData (the glTF scene extras), "clips": [names]}
// Exit code: 0 on success, 2 on usage/IO/loading problems (one line on stderr).
// process.exitCode is set instead of calling process.exit(), which can cut a piped report off.
import { readFile } from "node:fs/promises";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";

function parse(buffer) {
  // GLTFLoader.parse takes the ArrayBuffer directly, so no FileLoader/fetch is involved
  const loader = new GLTFLoader();
  return new Promise((resolve, reject) => loader.parse(buffer, "", resolve, reject));
}

function fail(message) {
  process.stderr.write(`three_probe: ${message}\n`);
  process.exitCode = 2;
}

async function main() {
  const [path, clipName, timesArg] = process.argv.slice(2);
  if (!path || !clipName || !timesArg) {
    fail("usage: node three_probe.mjs FILE.glb CLIP T0[,T1,...]");
    return;
  }
  const times = timesArg.split(",").map(Number);
  const data = await readFile(path);
  const gltf = await parse(data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength));
  const clip = gltf.animations.find((a) => a.name === clipName);
  if (!clip) {
    fail(`no clip named ${clipName} (have: ${gltf.animations.map((a) => a.name).join(", ")})`);
    return;
  }
  const root = gltf.scene;
  const bones = [];
  root.traverse((o) => {
    if (o.isBone) bones.push(o);
  });
  const mixer = new THREE.AnimationMixer(root);
  const action = mixer.clipAction(clip);
  action.setLoop(THREE.LoopOnce, 1);   // sample the last key, not the wrap to the first
  action.clampWhenFinished = true;
  action.play();
  const positions = [];
  const p = new THREE.Vector3();
  for (const t of times) {
    mixer.setTime(t);
    root.updateMatrixWorld(true);
    positions.push(bones.map((b) => b.getWorldPosition(p).toArray()));
  }
  const out = {
    clip: clip.name,
    duration: clip.duration,
    bones: bones.map((b) => b.name),
    times,
    positions,
    userData: root.userData,
    clips: gltf.animations.map((a) => a.name),
  };
  process.stdout.write(JSON.stringify(out) + "\n");
}

main().catch((e) => fail(e && e.message ? e.message : String(e)));
