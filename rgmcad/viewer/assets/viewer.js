// rgmcad replay viewer: plays a recorded run (see rgmcad/viewer/recording.py for the data).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const data = JSON.parse(document.getElementById('rgmcad-replay-data').textContent);
const root = document.getElementById('rgmcad-replay');
const view = root.querySelector('.view');

function decode(b64, Type) {
  const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  return new Type(bytes.buffer);
}
const times = decode(data.times, Float32Array);
const positions = decode(data.positions, Int16Array);
const quaternions = decode(data.quaternions, Int16Array);
const duration = times[times.length - 1];
const nMoving = data.moving.length;

// --- scene ---------------------------------------------------------------------------------
const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f5f7);
scene.add(new THREE.HemisphereLight(0xffffff, 0x8d8a84, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
scene.add(sun);

const lo = new THREE.Vector3(...data.bounds[0]);
const hi = new THREE.Vector3(...data.bounds[1]);
const centre = lo.clone().add(hi).multiplyScalar(0.5);
const radius = Math.max(hi.clone().sub(lo).length() / 2, 0.01);

const geometries = data.meshes.map((m) => {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(decode(m.vertices, Float32Array), 3));
  g.setIndex(new THREE.BufferAttribute(decode(m.faces, m.index === 'u2' ? Uint16Array : Uint32Array), 1));
  g.computeVertexNormals();
  return g;
});
const objects = data.bodies.map((b) => {
  const material = new THREE.MeshStandardMaterial({
    color: new THREE.Color().setRGB(...b.color, THREE.SRGBColorSpace), flatShading: true, roughness: 0.65, metalness: 0.05 });
  const mesh = new THREE.Mesh(geometries[b.mesh], material);
  mesh.position.set(...b.position);
  mesh.quaternion.set(...b.quaternion);
  mesh.name = b.name;
  scene.add(mesh);
  return mesh;
});
data.planes.forEach((p, i) => {
  const m = new THREE.Matrix4().fromArray(p);
  const size = radius * 3.5;
  const rgb = data.plane_colors && data.plane_colors[i];  // absent from pages of older payloads
  const color = rgb ? new THREE.Color().setRGB(...rgb, THREE.SRGBColorSpace) : new THREE.Color(0xdedbd4);
  const plane = new THREE.Mesh(new THREE.PlaneGeometry(size, size),
    new THREE.MeshStandardMaterial({ color, roughness: 0.9, side: THREE.DoubleSide }));
  const grid = new THREE.GridHelper(size, Math.round(size / 0.05), 0xb9b5ac, 0xcdc9c0);
  grid.rotation.x = Math.PI / 2;  // the helper lies in x-z; the plane's own frame has +z up
  grid.position.z = radius * 1e-3;
  const holder = new THREE.Group();
  holder.add(plane, grid);
  holder.applyMatrix4(m);
  // centre the finite plane under the machine
  const normal = new THREE.Vector3(0, 0, 1).transformDirection(m);
  const onPlane = centre.clone().sub(normal.clone().multiplyScalar(centre.clone().sub(holder.position).dot(normal)));
  holder.position.copy(onPlane);
  scene.add(holder);
});

const camera = new THREE.PerspectiveCamera(40, 1, radius / 50, radius * 40);
camera.up.set(0, 0, 1);
const vertical = data.planes.map((p) => new THREE.Vector3(p[8], p[9], p[10])).find((n) => Math.abs(n.z) < 0.5);
const direction = vertical ? vertical.clone().add(new THREE.Vector3(0, 0, 0.15)) : new THREE.Vector3(0.35, -1.0, 0.75);
direction.normalize();
camera.position.copy(centre.clone().add(direction.clone().multiplyScalar(radius / Math.tan(THREE.MathUtils.degToRad(20)) * 0.8)));
// light from above and behind the viewer's first position, so the faces it looks at are lit
sun.position.copy(centre.clone().add(direction.clone().add(new THREE.Vector3(0.3, 0, 1)).multiplyScalar(radius * 4)));
sun.target.position.copy(centre);
scene.add(sun.target);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.copy(centre);

// The camera never goes under the floor: the highest horizontal plane under the layout, or,
// without one, the layout's lowest point. Orbiting stops short of the horizon (the polar
// angle is measured from camera.up, +z) and panning stops with the target on the floor, so
// the camera, above the target, stays above the floor.
const floorZ = data.planes.map((p) => [new THREE.Vector3(p[8], p[9], p[10]), new THREE.Vector3(p[12], p[13], p[14])])
  .filter(([n]) => Math.abs(n.z) > 0.5)
  .map(([n, o]) => o.z - (n.x * (centre.x - o.x) + n.y * (centre.y - o.y)) / n.z)
  .reduce((a, b) => Math.max(a, b), -Infinity);
const floor = Number.isFinite(floorZ) ? floorZ : lo.z;
controls.maxPolarAngle = Math.PI / 2 - 0.05;
function keepAboveFloor() {
  const rise = Math.max(floor - controls.target.z, floor + radius * 1e-3 - camera.position.z, 0);
  if (rise > 0) {  // lift target and camera together: the view keeps its direction
    controls.target.z += rise;
    camera.position.z += rise;
  }
}
controls.addEventListener('change', keepAboveFloor);
controls.update();
controls.saveState();  // the framing the reset-view button returns to

// --- playback ------------------------------------------------------------------------------
const ui = {
  play: root.querySelector('.play'),
  scrub: root.querySelector('.scrub'),
  clock: root.querySelector('.clock'),
  speeds: root.querySelectorAll('.speed'),
  loop: root.querySelector('.loop'),
  head: root.querySelector('.playhead'),
  events: [...root.querySelectorAll('[data-event]')],
  reset: root.querySelector('.reset-view'),  // absent from pages written before them
  names: root.querySelector('.names'),
};
const state = { t: 0, playing: true, speed: 1, last: null };
const qa = new THREE.Quaternion(), qb = new THREE.Quaternion();

function frameAt(t) {
  let a = 0, b = times.length - 1;
  if (t >= times[b]) return [b, b, 0];
  while (b - a > 1) {
    const m = (a + b) >> 1;
    if (times[m] <= t) a = m; else b = m;
  }
  return [a, b, (t - times[a]) / Math.max(times[b] - times[a], 1e-9)];
}

function pose(t) {
  const [a, b, w] = frameAt(t);
  for (let k = 0; k < nMoving; k++) {
    const obj = objects[data.moving[k]];
    const pa = (a * nMoving + k) * 3, pb = (b * nMoving + k) * 3;
    for (let i = 0; i < 3; i++) {
      const u = positions[pa + i] * (1 - w) + positions[pb + i] * w;
      obj.position.setComponent(i, data.centre[i] + (u / 32767) * data.half[i]);
    }
    const ra = (a * nMoving + k) * 4, rb = (b * nMoving + k) * 4;
    qa.set(quaternions[ra], quaternions[ra + 1], quaternions[ra + 2], quaternions[ra + 3]).normalize();
    qb.set(quaternions[rb], quaternions[rb + 1], quaternions[rb + 2], quaternions[rb + 3]).normalize();
    obj.quaternion.slerpQuaternions(qa, qb, w);
  }
}

function showTime() {
  ui.clock.textContent = `${state.t.toFixed(3)} s / ${duration.toFixed(3)} s`;
  ui.scrub.value = String(Math.round((state.t / Math.max(duration, 1e-9)) * 1000));
  ui.head.style.left = `${(100 * state.t) / Math.max(duration, 1e-9)}%`;
  ui.play.textContent = state.playing ? 'Pause' : 'Play';
  for (const el of ui.events) {
    const time = el.dataset.time === '' ? null : Number(el.dataset.time);
    const reached = time !== null && state.t >= time - 1e-6;  // frame times are float32
    el.classList.toggle('lit', reached && el.dataset.state === 'success');
    el.classList.toggle('failed', reached && el.dataset.state === 'failure');
  }
}

// --- part names: under the pointer, and on request beside every object ---------------------
function overlay(className) {
  const el = document.createElement('div');
  el.className = className;
  view.appendChild(el);
  return el;
}
const tip = overlay('hover-name');
tip.hidden = true;
const tags = overlay('name-tags');
tags.hidden = true;
const meshCentres = geometries.map((g) => {
  g.computeBoundingBox();
  return g.boundingBox.getCenter(new THREE.Vector3());
});
// one tag per object, a domino run's once (at its first domino): the PNG's labels
const tagged = new Map();
data.bodies.forEach((b, k) => { if (!tagged.has(b.label || b.name)) tagged.set(b.label || b.name, k); });
const tagOf = [...tagged].map(([text, k]) => {
  const el = document.createElement('span');
  el.textContent = text;
  tags.appendChild(el);
  return [el, k];
});
const ndc = new THREE.Vector3();

function onScreen(k) {
  // [x, y] in the view's pixels of body k's centre, or null when behind the camera
  objects[k].updateMatrixWorld();
  ndc.copy(meshCentres[data.bodies[k].mesh]).applyMatrix4(objects[k].matrixWorld).project(camera);
  if (ndc.z < -1 || ndc.z > 1) return null;
  return [(ndc.x + 1) / 2 * view.clientWidth, (1 - ndc.y) / 2 * view.clientHeight];
}

function placeTags() {
  if (tags.hidden) return;
  for (const [el, k] of tagOf) {
    const at = onScreen(k);
    el.hidden = at === null;
    if (at) el.style.transform = `translate(${at[0].toFixed(1)}px, ${at[1].toFixed(1)}px) translate(-50%, -130%)`;
  }
}

function showNames(on) {
  tags.hidden = !on;
  if (ui.names) ui.names.checked = on;
  placeTags();
}

const raycaster = new THREE.Raycaster();
const pointer = { inside: false, down: false, x: 0, y: 0 };
let hovered = null;

function partAt(x, y) {
  // the body drawn at (x, y), view pixels: the nearest one the ray through it meets
  raycaster.setFromCamera(new THREE.Vector2(x / view.clientWidth * 2 - 1, 1 - y / view.clientHeight * 2), camera);
  const hit = raycaster.intersectObjects(objects, false)[0];
  return hit ? hit.object : null;
}

function hover() {
  const part = pointer.inside && !pointer.down ? partAt(pointer.x, pointer.y) : null;
  if (hovered && hovered !== part) hovered.material.emissive.setHex(0x000000);
  hovered = part;
  tip.hidden = part === null;
  if (!part) return;
  part.material.emissive.setHex(0x303030);
  tip.textContent = part.name;
  tip.style.transform = `translate(${pointer.x + 14}px, ${pointer.y + 10}px)`;
}

const canvas = renderer.domElement;
canvas.addEventListener('pointermove', (e) => {
  const box = view.getBoundingClientRect();
  Object.assign(pointer, { inside: true, x: e.clientX - box.left, y: e.clientY - box.top });
});
canvas.addEventListener('pointerleave', () => { pointer.inside = false; });
canvas.addEventListener('pointerdown', () => { pointer.down = true; });
window.addEventListener('pointerup', () => { pointer.down = false; });

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);

function tick(now) {
  if (state.last !== null && state.playing) {
    state.t += ((now - state.last) / 1000) * state.speed;
    if (state.t > duration) {
      if (ui.loop.checked) state.t = 0; else { state.t = duration; state.playing = false; }
    }
  }
  state.last = now;
  pose(state.t);
  showTime();
  controls.update();
  hover();  // every frame: the parts move under a still pointer
  renderer.render(scene, camera);
  placeTags();
  requestAnimationFrame(tick);
}

ui.play.addEventListener('click', () => { state.playing = !state.playing; if (state.playing && state.t >= duration) state.t = 0; });
ui.scrub.addEventListener('input', () => {
  state.t = (Number(ui.scrub.value) / 1000) * duration;
  pose(state.t);
  showTime();
});
for (const button of ui.speeds) {
  button.addEventListener('click', () => {
    state.speed = Number(button.dataset.speed);
    for (const b of ui.speeds) b.classList.toggle('on', b === button);
  });
}
if (ui.reset) ui.reset.addEventListener('click', () => controls.reset());
if (ui.names) ui.names.addEventListener('change', () => showNames(ui.names.checked));
window.addEventListener('keydown', (e) => {
  if (e.code === 'Space' && e.target.tagName !== 'INPUT') { e.preventDefault(); ui.play.click(); }
  const typing = e.target.isContentEditable || e.target.tagName === 'TEXTAREA'
    || (e.target.tagName === 'INPUT' && !['checkbox', 'range', 'button'].includes(e.target.type));
  if (typing || e.ctrlKey || e.metaKey || e.altKey) return;  // Ctrl+R still reloads
  if (e.key === 'r' || e.key === 'R') controls.reset();
  if (e.key === 'n' || e.key === 'N') showNames(tags.hidden);
});

resize();
pose(0);
renderer.render(scene, camera);
window.rgmcadViewer = {
  duration, frames: times.length,
  time: () => state.t,
  playing: () => state.playing,
  play: () => { state.playing = true; },
  pause: () => { state.playing = false; },
  seek: (t) => { state.t = Math.min(Math.max(t, 0), duration); pose(state.t); showTime(); },
  setSpeed: (s) => { state.speed = s; },
  // read-only views for tests and debugging: copies, not the live objects
  get camera() {
    return { position: camera.position.toArray(), target: controls.target.toArray(), up: camera.up.toArray() };
  },
  // a view carried over from another page of the same machine (the live page's next
  // picture): camera, speed, loop and names as the user left them; the reset button still
  // returns to this page's own framing
  get view() {
    return { camera: this.camera, speed: state.speed, loop: ui.loop.checked, names: !tags.hidden };
  },
  setView: (v) => {
    if (v.camera) {
      camera.position.fromArray(v.camera.position);
      controls.target.fromArray(v.camera.target);
      keepAboveFloor();
      controls.update();
    }
    if (v.speed) {
      state.speed = v.speed;
      for (const b of ui.speeds) b.classList.toggle('on', Number(b.dataset.speed) === v.speed);
    }
    if (v.loop !== undefined) ui.loop.checked = v.loop;
    if (v.names !== undefined) showNames(v.names);
  },
  floor,
  resetView: () => controls.reset(),
  showNames,
  namesShown: () => !tags.hidden,
  // where body `name`'s centre is drawn, in page pixels (null: not a body, or behind the camera)
  screenPoint: (name) => {
    const k = objects.findIndex((o) => o.name === name);
    const at = k < 0 ? null : onScreen(k);
    if (!at) return null;
    const box = view.getBoundingClientRect();
    return [box.left + at[0], box.top + at[1]];
  },
  hovered: () => (tip.hidden ? null : tip.textContent),
};
root.dataset.ready = '1';
requestAnimationFrame(tick);
