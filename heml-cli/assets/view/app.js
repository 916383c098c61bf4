// heml view: draws the live surface sent by the `heml` binary and sends the
// person's commands back (protocol: heml-cli/src/cli/view/protocol.rs).
import * as THREE from 'three';
import { OrbitControls } from '/vendor/three/OrbitControls.js';

const BACKGROUND = 0x1b1d23;
const HEADER = 32;
const canvas = document.getElementById('view');
// A browser without a GPU renders WebGL on the CPU (SwiftShader, llvmpipe), on the
// cores the simulation steps on: there, no multisampling and one sample per CSS
// pixel (each costs the simulation time; ?aa=1 forces them back).
const software = (() => {
  const gl = document.createElement('canvas').getContext('webgl2');
  const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
  const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  if (gl) gl.getExtension('WEBGL_lose_context')?.loseContext();
  return /swiftshader|llvmpipe|softpipe|software/i.test(name);
})();
const quality = new URLSearchParams(location.search).get('aa') === '1' || !software;
const renderer = new THREE.WebGLRenderer({ canvas, antialias: quality });
renderer.setPixelRatio(quality ? window.devicePixelRatio || 1 : 1);
renderer.setClearColor(BACKGROUND);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, 1, 1e-4, 100);
const controls = new OrbitControls(camera, canvas);
scene.add(new THREE.HemisphereLight(0xffffff, 0x303040, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
scene.add(sun);

const $ = (id) => document.getElementById(id);
const state = {
  mesh: null, geometry: null, surface: null, wire: null, fixedPoints: null, fixedIndex: [],
  frames: 0, drawn: 0, bytes: 0, lastFrame: -1, lastTime: 0, fpsCount: 0, fpsStart: performance.now(),
  status: null, E0: null, field: 'displacement', software,
  // the newest frame not drawn yet, and whether anything changed since the last draw
  pending: null, dirty: true,
};
window.hemlView = state;

const ws = new WebSocket(`ws://${location.host}/ws`);
ws.binaryType = 'arraybuffer';
const send = (msg) => { if (ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(msg)); };
ws.onclose = () => message('connection closed: reload the page when the server runs again');
ws.onmessage = (ev) => {
  if (typeof ev.data === 'string') {
    const msg = JSON.parse(ev.data);
    if (msg.type === 'mesh') onMesh(msg);
    else if (msg.type === 'status') onStatus(msg);
    else if (msg.type === 'reply') onReply(msg);
  } else {
    // drawn at the next animation frame; a newer one arriving before replaces it.
    // The ack lets the server send the next one: at most one frame is ever queued
    // between the simulation and the page, so the page always gets a fresh one
    state.pending = ev.data;
    state.frames++; state.fpsCount++; state.bytes = ev.data.byteLength;
    send({ type: 'ack' });
  }
};

function onReply(r) {
  // a refused grasp_start already said why: its moves and release add nothing
  if (!r.ok && /^grasp_(move|end)$/.test(r.command) && r.message.includes('no grasp in progress')) return;
  if (!r.ok || r.message) message(`${r.command}: ${r.message}`, !r.ok);
}

function message(text, bad) {
  const m = $('message');
  m.textContent = text;
  m.style.color = bad ? '#f07474' : '#f0c674';
}

// the colour map (turbo-like), t in [0, 1]
const STOPS = [[0.19, 0.07, 0.23], [0.27, 0.53, 0.98], [0.1, 0.89, 0.71], [0.64, 0.99, 0.24], [0.98, 0.73, 0.22], [0.89, 0.27, 0.04], [0.48, 0.02, 0.01]];
function colour(t, out, k) {
  t = Math.min(1, Math.max(0, t)) * (STOPS.length - 1);
  const i = Math.min(STOPS.length - 2, Math.floor(t)), f = t - i;
  for (let c = 0; c < 3; c++) out[3 * k + c] = STOPS[i][c] * (1 - f) + STOPS[i + 1][c] * f;
}

function onMesh(m) {
  state.mesh = m;
  if (state.surface) { scene.remove(state.surface, state.wire, state.fixedPoints); state.geometry.dispose(); }
  const g = new THREE.BufferGeometry();
  const n = m.nodes.length;
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(m.rest), 3).setUsage(THREE.DynamicDrawUsage));
  g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * n).fill(0.6), 3).setUsage(THREE.DynamicDrawUsage));
  const index = n > 65535 ? new Uint32Array(m.triangles.flat()) : new Uint16Array(m.triangles.flat());
  g.setIndex(new THREE.BufferAttribute(index, 1));
  g.computeVertexNormals();
  g.computeBoundingSphere();
  state.geometry = g;
  state.surface = new THREE.Mesh(g, new THREE.MeshPhongMaterial({ vertexColors: true, side: THREE.DoubleSide, shininess: 30 }));
  state.wire = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ color: 0x000000, wireframe: true, transparent: true, opacity: 0.35 }));
  state.wire.visible = $('wire').checked;
  state.fixedIndex = m.fixed;
  const fg = new THREE.BufferGeometry();
  fg.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * m.fixed.length), 3));
  state.fixedPoints = new THREE.Points(fg, new THREE.PointsMaterial({ color: 0x5fd7ff, size: 4, sizeAttenuation: false }));
  scene.add(state.surface, state.wire, state.fixedPoints);
  updateFixed();
  $('mode').textContent = `(${m.mode})`;
  $('source').textContent = m.source;
  if (m.version === 0 || !state.fitted) fit(m.bbox);
  state.dirty = true;
}

function fit(bbox) {
  const lo = new THREE.Vector3(...bbox[0]), hi = new THREE.Vector3(...bbox[1]);
  const centre = lo.clone().add(hi).multiplyScalar(0.5);
  const size = hi.clone().sub(lo).length();
  controls.target.copy(centre);
  camera.position.copy(centre).add(new THREE.Vector3(0.9, -1.6, 0.8).normalize().multiplyScalar(2.2 * size));
  camera.up.set(0, 0, 1);
  camera.near = size / 100; camera.far = size * 100;
  camera.updateProjectionMatrix();
  controls.update();
  state.fitted = true;
}

function updateFixed() {
  const p = state.geometry.attributes.position.array, f = state.fixedPoints.geometry.attributes.position;
  state.fixedIndex.forEach((k, j) => { f.array[3 * j] = p[3 * k]; f.array[3 * j + 1] = p[3 * k + 1]; f.array[3 * j + 2] = p[3 * k + 2]; });
  f.needsUpdate = true;
  state.fixedPoints.geometry.computeBoundingSphere();
}

function onFrame(buf) {
  if (!state.geometry) return;
  const h = new DataView(buf);
  const frame = h.getUint32(0, true), n = h.getUint32(4, true), time = h.getFloat64(8, true);
  const lo = h.getFloat32(16, true), hi = h.getFloat32(20, true);
  const pos = state.geometry.attributes.position;
  if (n !== pos.count || buf.byteLength !== HEADER + 16 * n) return; // a frame of an older mesh
  pos.array.set(new Float32Array(buf, HEADER, 3 * n));
  pos.needsUpdate = true;
  const values = new Float32Array(buf, HEADER + 12 * n, n);
  const col = state.geometry.attributes.color;
  const span = hi > lo ? hi - lo : 1;
  for (let k = 0; k < n; k++) colour((values[k] - lo) / span, col.array, k);
  col.needsUpdate = true;
  state.geometry.computeVertexNormals();
  state.geometry.computeBoundingSphere();
  updateFixed();
  $('lo').textContent = lo.toPrecision(3); $('hi').textContent = hi.toPrecision(3);
  state.drawn++; state.lastFrame = frame; state.lastTime = time;
}

function fmt(x, unit, digits = 3) { return x === null || x === undefined || Number.isNaN(x) ? '–' : `${Number(x).toPrecision(digits)}${unit}`; }

function onStatus(s) {
  state.status = s;
  $('time').textContent = `${s.time.toFixed(3)} s`;
  $('rtf').textContent = fmt(s.real_time_factor, '×');
  $('steptime').textContent = `${fmt(s.step_ms_p50, '')} / ${fmt(s.step_ms_p99, ' ms')}`;
  $('integrator').textContent = `${s.integrator}, ${fmt(s.dt, ' s')}`;
  $('minj').textContent = fmt(s.min_j, '', 4);
  $('force').textContent = s.tool_force ? `${Math.hypot(...s.tool_force).toPrecision(3)} N` : '–';
  if (s.tool || (state.tool && state.tool.visible)) { drawTool(s.tool, s.tool_force); state.dirty = true; }
  $('law').textContent = s.law ? `${s.law} ${s.law_params.map(([k, v]) => `${k}=${v.toPrecision(3)}`).join(' ')}` : '–';
  $('pause').textContent = s.paused ? 'resume' : 'pause';
  if (s.error) message(`stopped: ${s.error}`, true);
  const E = (s.scene_params || []).find(([k]) => k === 'E');
  // the field follows the server's E when it changes, never while the person types
  if (E && state.E0 === null) state.E0 = E[1];
  if (E && E[1] !== state.Eshown) { state.Eshown = E[1]; $('E').value = E[1]; }
}

// the tool: a capsule from its tip along its axis, and the force on it as an arrow
// (its length: 1 N per tenth of the body's size)
function drawTool(tool, force) {
  if (!tool) { if (state.tool) state.tool.visible = false; if (state.arrow) state.arrow.visible = false; return; }
  const key = `${tool.radius}/${tool.length}`;
  if (!state.tool || state.toolKey !== key) {
    if (state.tool) scene.remove(state.tool);
    const g = new THREE.CapsuleGeometry(tool.radius, tool.length, 4, 16);
    g.translate(0, tool.length / 2 + tool.radius, 0); // tip at the origin, along +y
    state.tool = new THREE.Mesh(g, new THREE.MeshPhongMaterial({ color: 0xb0b8c8, shininess: 80 }));
    state.toolKey = key;
    scene.add(state.tool);
  }
  const axis = new THREE.Vector3(...tool.axis).normalize();
  state.tool.position.set(...tool.tip);
  state.tool.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), axis);
  state.tool.visible = true;
  if (!state.arrow) { state.arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, 0xffd166); scene.add(state.arrow); }
  const f = force ? new THREE.Vector3(...force) : new THREE.Vector3();
  const size = state.mesh ? new THREE.Vector3(...state.mesh.bbox[1]).sub(new THREE.Vector3(...state.mesh.bbox[0])).length() : 1;
  state.arrow.visible = f.length() > 0;
  if (state.arrow.visible) {
    state.arrow.position.set(...tool.tip);
    state.arrow.setDirection(f.clone().normalize());
    state.arrow.setLength(0.1 * size * f.length(), 0.02 * size, 0.01 * size);
  }
}

$('pause').onclick = () => send({ type: state.status && state.status.paused ? 'resume' : 'pause' });
$('step').onclick = () => send({ type: 'step' });
$('reset').onclick = () => send({ type: 'reset' });
$('field').onchange = (e) => { state.field = e.target.value; send({ type: 'field', field: e.target.value }); };
$('wire').onchange = (e) => { if (state.wire) state.wire.visible = e.target.checked; state.dirty = true; };
const setE = (v) => { if (Number.isFinite(v) && v > 0) send({ type: 'set_param', name: 'E', value: v }); };
$('setE').onclick = () => setE(parseFloat($('E').value));
$('Eslider').onchange = (e) => { if (state.E0) { const v = state.E0 * Math.pow(10, parseFloat(e.target.value)); $('E').value = v.toPrecision(4); setE(v); } };

// ---- picking: grasp (drag on the tissue), cut (Shift+drag), tool (Alt+drag) ----
const raycaster = new THREE.Raycaster();
function ndc(ev) {
  const r = canvas.getBoundingClientRect();
  return new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
}
function viewPlane(through) {
  const normal = new THREE.Vector3();
  camera.getWorldDirection(normal);
  return new THREE.Plane().setFromNormalAndCoplanarPoint(normal, through);
}
function onPlane(ev, plane) {
  raycaster.setFromCamera(ndc(ev), camera);
  const p = new THREE.Vector3();
  return raycaster.ray.intersectPlane(plane, p) ? p : null;
}
let drag = null;
canvas.addEventListener('pointerdown', (ev) => {
  if (!state.surface || ev.button !== 0) return;
  const centre = controls.target.clone();
  if (ev.shiftKey || ev.altKey) {
    const plane = viewPlane(centre);
    const p = onPlane(ev, plane);
    if (!p) return;
    drag = { kind: ev.shiftKey ? 'cut' : 'tool', plane, start: p };
  } else {
    raycaster.setFromCamera(ndc(ev), camera);
    const hit = raycaster.intersectObject(state.surface)[0];
    if (!hit) return; // background: orbit
    const f = hit.face, pos = state.geometry.attributes.position;
    let best = f.a, bestD = Infinity;
    for (const k of [f.a, f.b, f.c]) {
      const d = new THREE.Vector3().fromBufferAttribute(pos, k).distanceTo(hit.point);
      if (d < bestD) { bestD = d; best = k; }
    }
    send({ type: 'grasp_start', node: state.mesh.nodes[best] });
    drag = { kind: 'grasp', plane: viewPlane(hit.point) };
  }
  controls.enabled = false;
  canvas.setPointerCapture(ev.pointerId);
  ev.stopImmediatePropagation();
}, { capture: true });
canvas.addEventListener('pointermove', (ev) => {
  if (!drag) return;
  const p = onPlane(ev, drag.plane);
  if (!p) return;
  if (drag.kind === 'grasp') send({ type: 'grasp_move', target: p.toArray() });
  if (drag.kind === 'tool') {
    const axis = new THREE.Vector3(); camera.getWorldDirection(axis);
    send({ type: 'tool_move', position: p.toArray(), axis: axis.negate().toArray() });
  }
  drag.end = p;
});
canvas.addEventListener('pointerup', () => {
  if (!drag) return;
  if (drag.kind === 'grasp') send({ type: 'grasp_end' });
  if (drag.kind === 'cut' && drag.end) {
    // the blade: the triangle from the eye through the two ends of the stroke, past the body
    const eye = camera.position.clone();
    const far = (p) => eye.clone().add(p.clone().sub(eye).multiplyScalar(3));
    send({ type: 'cut', blade: [eye.toArray(), far(drag.start).toArray(), far(drag.end).toArray()] });
  }
  drag = null;
  controls.enabled = true;
});

// ---- for tests and measurements: pixels of the organ in the drawn canvas ----
state.probe = () => {
  const box = new THREE.Box3().setFromBufferAttribute(state.geometry.attributes.position);
  const w = canvas.width, h = canvas.height;
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (let c = 0; c < 8; c++) {
    const v = new THREE.Vector3(c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y, c & 4 ? box.max.z : box.min.z).project(camera);
    const px = (v.x + 1) / 2 * w, py = (1 - v.y) / 2 * h;
    x0 = Math.min(x0, px); x1 = Math.max(x1, px); y0 = Math.min(y0, py); y1 = Math.max(y1, py);
  }
  x0 = Math.max(0, Math.floor(x0)); y0 = Math.max(0, Math.floor(y0));
  x1 = Math.min(w, Math.ceil(x1)); y1 = Math.min(h, Math.ceil(y1));
  // drawn and read in one task: the drawing buffer is not preserved after it
  renderer.render(scene, camera);
  const c2 = document.createElement('canvas'); c2.width = w; c2.height = h;
  const ctx = c2.getContext('2d'); ctx.drawImage(canvas, 0, 0);
  const data = ctx.getImageData(0, 0, w, h).data;
  const bg = [(BACKGROUND >> 16) & 255, (BACKGROUND >> 8) & 255, BACKGROUND & 255];
  let inside = 0, outside = 0, area = 0;
  for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
    const i = 4 * (y * w + x);
    const differs = Math.abs(data[i] - bg[0]) + Math.abs(data[i + 1] - bg[1]) + Math.abs(data[i + 2] - bg[2]) > 30;
    const inBox = x >= x0 && x < x1 && y >= y0 && y < y1;
    if (inBox) area++;
    if (differs && inBox) inside++; else if (differs) outside++;
  }
  return { rect: [x0, y0, x1, y1], inside, outside, area, width: w, height: h, webgl: !!renderer.getContext() };
};

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== Math.floor(w * renderer.getPixelRatio()) || canvas.height !== Math.floor(h * renderer.getPixelRatio())) {
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    // centre the body in the part of the window the panel leaves free
    const shift = Math.min($('panel').offsetWidth + 20, 0.4 * w) / 2;
    camera.setViewOffset(w, h, -shift, 0, w, h);
    camera.updateProjectionMatrix();
    state.dirty = true;
  }
}
controls.addEventListener('change', () => { state.dirty = true; });
function animate() {
  resize();
  const now = performance.now();
  if (now - state.fpsStart >= 1000) {
    state.fps = state.fpsCount * 1000 / (now - state.fpsStart);
    state.fpsCount = 0; state.fpsStart = now;
    $('fps').textContent = state.fps.toFixed(1);
    $('bytes').textContent = state.bytes ? state.bytes.toLocaleString() : '–';
  }
  controls.update();
  // the newest frame only, and a draw only when something changed: a page that
  // shows a still scene costs nothing, one that falls behind skips frames
  const buf = state.pending;
  state.pending = null;
  if (buf) { onFrame(buf); state.dirty = true; }
  if (state.dirty) {
    sun.position.copy(camera.position);
    renderer.render(scene, camera);
    state.dirty = false;
  }
  requestAnimationFrame(animate);
}
animate();
