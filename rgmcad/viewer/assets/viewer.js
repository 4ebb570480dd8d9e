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
for (const p of data.planes) {
  const m = new THREE.Matrix4().fromArray(p);
  const size = radius * 3.5;
  const plane = new THREE.Mesh(new THREE.PlaneGeometry(size, size),
    new THREE.MeshStandardMaterial({ color: 0xdedbd4, roughness: 0.9, side: THREE.DoubleSide }));
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
}

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
controls.update();

// --- playback ------------------------------------------------------------------------------
const ui = {
  play: root.querySelector('.play'),
  scrub: root.querySelector('.scrub'),
  clock: root.querySelector('.clock'),
  speeds: root.querySelectorAll('.speed'),
  loop: root.querySelector('.loop'),
  head: root.querySelector('.playhead'),
  events: [...root.querySelectorAll('[data-event]')],
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
  renderer.render(scene, camera);
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
window.addEventListener('keydown', (e) => {
  if (e.code === 'Space' && e.target.tagName !== 'INPUT') { e.preventDefault(); ui.play.click(); }
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
};
root.dataset.ready = '1';
requestAnimationFrame(tick);
