// ccm-slam-dds live map view (issue 14). Polls the server's JSON API about twice a second and
// asks only for what changed since the version it holds (/api/map?since=N), so an update
// costs the same whatever the map's size. Draws each agent's keyframe trajectory in its
// colour, the (decimated) map points, covisibility edges above a weight and each agent's
// newest camera as a frustum; server maps that have not fused yet are laid side by side.
// The map frame is the first agent camera's: x right, y down, z forward, so "up" is -y.
'use strict';

const POLL_MS = 500;
const COLOURS = [0x4e79a7, 0xf28e2b, 0x59a14f, 0xe15759, 0xb07aa1, 0x76b7b2, 0xedc948, 0xff9da7, 0x9c755f];
const colourOf = (agent) => COLOURS[(Number(agent) - 1 + COLOURS.length) % COLOURS.length];
const agentOf = (id) => id.split(':')[0];
const counterOf = (id) => Number(id.split(':')[1]);

const state = {
  version: 0, eventsNext: 0, updates: 0, bytes: 0, minWeight: 100, status: null,
  keyframes: new Map(),  // id -> {map, p: [x y z qx qy qz qw]}
  points: new Map(),     // id -> [x, y, z]
  edges: new Map(),      // "a|b" -> weight
  events: [], fitted: false, topView: false, dirty: true,
};
window.ccmMapView = state;  // scripts and tests read the page's state here

// ---- three.js scene -------------------------------------------------------------------
const view = document.getElementById('view');
let renderer = null, scene = null, camera = null, controls = null;
const layers = {};
try {
  renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  view.appendChild(renderer.domElement);
  scene = new THREE.Scene();
  scene.background = new THREE.Color(0x11151c);
  camera = new THREE.PerspectiveCamera(55, 1, 0.01, 10000);
  camera.up.set(0, -1, 0);
  camera.position.set(0, -5, -8);
  controls = new THREE.OrbitControls(camera, renderer.domElement);
  for (const name of ['points', 'edges', 'trajectories', 'frusta']) {
    layers[name] = new THREE.Group();
    scene.add(layers[name]);
  }
} catch (e) {
  renderer = null;
  view.innerHTML = '<div class="no-webgl">3-D view unavailable (no WebGL: ' + e.message + '); the panel still updates.</div>';
}

function resize() {
  if (!renderer) return;
  const w = view.clientWidth || 800, h = view.clientHeight || 600;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

function clearGroup(g) {
  while (g.children.length) {
    const c = g.children.pop();
    c.geometry.dispose();
    c.material.dispose();
  }
}

function lineSegments(positions, colours, opacity) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(positions, 3));
  g.setAttribute('color', new THREE.Float32BufferAttribute(colours, 3));
  return new THREE.LineSegments(g, new THREE.LineBasicMaterial({
    vertexColors: THREE.VertexColors, transparent: opacity < 1, opacity }));
}

// Unfused maps have unrelated frames: each gets an x offset so they sit side by side.
function mapOffsets() {
  const boxes = new Map();
  for (const kf of state.keyframes.values()) {
    const b = boxes.get(kf.map) || { min: Infinity, max: -Infinity };
    b.min = Math.min(b.min, kf.p[0]);
    b.max = Math.max(b.max, kf.p[0]);
    boxes.set(kf.map, b);
  }
  const ids = [...boxes.keys()].sort((a, b) => counterOf(a) - counterOf(b));
  const offsets = new Map();
  let x = 0;
  ids.forEach((id, i) => {
    const b = boxes.get(id);
    const width = Math.max(b.max - b.min, 1);
    offsets.set(id, i === 0 ? 0 : x - b.min);
    x = (i === 0 ? b.max : x + width) + Math.max(2, 0.2 * width);
  });
  return offsets;
}

function rebuildScene() {
  if (!renderer || !state.dirty) return;
  state.dirty = false;
  const offsets = mapOffsets();
  const kfMap = new Map();  // id -> position with offset
  for (const [id, kf] of state.keyframes) kfMap.set(id, [kf.p[0] + (offsets.get(kf.map) || 0), kf.p[1], kf.p[2]]);
  // Trajectories: each agent's keyframes in creation order, broken where the map changes.
  const byAgent = new Map();
  for (const [id, kf] of state.keyframes) {
    const a = agentOf(id);
    if (!byAgent.has(a)) byAgent.set(a, []);
    byAgent.get(a).push([counterOf(id), id, kf.map]);
  }
  const tp = [], tc = [];
  for (const [a, list] of byAgent) {
    list.sort((x, y) => x[0] - y[0]);
    const c = new THREE.Color(colourOf(a));
    for (let i = 1; i < list.length; ++i) {
      if (list[i][2] !== list[i - 1][2]) continue;
      tp.push(...kfMap.get(list[i - 1][1]), ...kfMap.get(list[i][1]));
      tc.push(c.r, c.g, c.b, c.r, c.g, c.b);
    }
  }
  clearGroup(layers.trajectories);
  const trajectories = lineSegments(tp, tc, 1);
  trajectories.material.depthTest = false;  // always on top of points and edges
  trajectories.renderOrder = 1;
  layers.trajectories.add(trajectories);
  // Covisibility edges.
  const ep = [], ec = [];
  for (const [key] of state.edges) {
    const [a, b] = key.split('|');
    if (!kfMap.has(a) || !kfMap.has(b)) continue;
    ep.push(...kfMap.get(a), ...kfMap.get(b));
    ec.push(0.45, 0.5, 0.58, 0.45, 0.5, 0.58);
  }
  clearGroup(layers.edges);
  layers.edges.add(lineSegments(ep, ec, 0.18));
  // Points, coloured by the agent that created them (offset by the map of a keyframe is not
  // known per point: points follow the map of their creator's newest keyframe).
  const agentMap = new Map();
  if (state.status) for (const a of state.status.agents) if (a.map) agentMap.set(String(a.id), a.map);
  const pp = new Float32Array(state.points.size * 3), pc = new Float32Array(state.points.size * 3);
  let n = 0;
  for (const [id, x] of state.points) {
    const a = agentOf(id), off = offsets.get(agentMap.get(a)) || 0;
    const c = new THREE.Color(colourOf(a)).lerp(new THREE.Color(0xffffff), 0.35);
    pp.set([x[0] + off, x[1], x[2]], 3 * n);
    pc.set([c.r, c.g, c.b], 3 * n);
    ++n;
  }
  clearGroup(layers.points);
  const pg = new THREE.BufferGeometry();
  pg.setAttribute('position', new THREE.BufferAttribute(pp, 3));
  pg.setAttribute('color', new THREE.BufferAttribute(pc, 3));
  layers.points.add(new THREE.Points(pg, new THREE.PointsMaterial({ size: 2, sizeAttenuation: false, vertexColors: THREE.VertexColors })));
  layers.points.visible = document.getElementById('show-points').checked;
  buildFrusta(offsets);
  if (!state.fitted && state.keyframes.size > 0) fitView();
}

function sceneSize() {
  const box = new THREE.Box3();
  for (const obj of [layers.trajectories]) box.expandByObject(obj);
  return box;
}

function buildFrusta(offsets) {
  clearGroup(layers.frusta);
  if (!state.status) return;
  const box = sceneSize();
  const s = Math.max(0.05, 0.04 * box.getSize(new THREE.Vector3()).length());
  const w = 0.6 * s, h = 0.45 * s, d = s;
  const corners = [[-w, -h, d], [w, -h, d], [w, h, d], [-w, h, d]];
  for (const a of state.status.agents) {
    if (!a.pose) continue;
    const q = new THREE.Quaternion(a.pose[3], a.pose[4], a.pose[5], a.pose[6]);
    const t = new THREE.Vector3(a.pose[0] + (offsets.get(a.map) || 0), a.pose[1], a.pose[2]);
    const world = corners.map((c) => new THREE.Vector3(...c).applyQuaternion(q).add(t));
    const pos = [];
    for (let i = 0; i < 4; ++i) {
      pos.push(t.x, t.y, t.z, world[i].x, world[i].y, world[i].z);
      const j = (i + 1) % 4;
      pos.push(world[i].x, world[i].y, world[i].z, world[j].x, world[j].y, world[j].z);
    }
    const c = new THREE.Color(colourOf(a.id));
    const col = [];
    for (let i = 0; i < pos.length / 3; ++i) col.push(c.r, c.g, c.b);
    layers.frusta.add(lineSegments(pos, col, 1));
  }
}

function fitView() {
  const box = sceneSize();
  if (box.isEmpty()) return;
  state.fitted = true;
  const centre = box.getCenter(new THREE.Vector3());
  const size = Math.max(box.getSize(new THREE.Vector3()).length(), 1);
  controls.target.copy(centre);
  if (state.topView) {
    camera.up.set(0, 0, 1);
    camera.position.set(centre.x, centre.y - 1.3 * size, centre.z);  // above: -y is up
  } else {
    camera.up.set(0, -1, 0);
    camera.position.set(centre.x - 0.3 * size, centre.y - 0.7 * size, centre.z - 0.9 * size);
  }
  controls.update();
}

function animate() {
  requestAnimationFrame(animate);
  if (!renderer) return;
  rebuildScene();
  controls.update();
  renderer.render(scene, camera);
}

// ---- data: apply the API's answers ----------------------------------------------------
function applyMap(m) {
  if (m.reset) {
    state.keyframes.clear();
    state.points.clear();
    state.edges.clear();
  } else {
    for (const id of m.removed.keyframes) state.keyframes.delete(id);
    for (const id of m.removed.points) state.points.delete(id);
    for (const [a, b] of m.removed.edges) state.edges.delete(a + '|' + b);
  }
  for (const k of m.keyframes) state.keyframes.set(k[0], { map: k[1], p: k.slice(2) });
  for (const p of m.points) state.points.set(p[0], p.slice(1));
  for (const e of m.edges) state.edges.set(e[0] + '|' + e[1], e[2]);
  if (m.version !== state.version || m.reset) state.dirty = true;
  state.version = m.version;
}

async function getJson(url) {
  const r = await fetch(url, { cache: 'no-store' });
  const text = await r.text();
  state.bytes += text.length;
  const body = JSON.parse(text);
  if (!r.ok) {
    const e = new Error(body.error || ('HTTP ' + r.status));
    e.status = r.status;
    throw e;
  }
  return body;
}

async function poll() {
  try {
    const status = await getJson('api/status');
    let map;
    try {
      map = await getJson('api/map?since=' + state.version + '&min_weight=' + state.minWeight);
    } catch (e) {
      if (e.status !== 400) throw e;
      state.version = 0;  // e.g. the server restarted with a lower version: reload in full
      map = await getJson('api/map?since=0&min_weight=' + state.minWeight);
    }
    const ev = await getJson('api/events?since=' + Math.min(state.eventsNext, status.totals.events));
    state.status = status;
    applyMap(map);
    state.events.push(...ev.events);
    state.eventsNext = ev.next;
    state.dirty = true;  // frusta follow the agents even when the map did not change
    state.updates += 1;
    renderPanel();
    setConnection(true, 'live, version ' + state.version);
  } catch (e) {
    setConnection(false, 'no answer from the server (' + e.message + '); retrying');
  }
  setTimeout(poll, POLL_MS);
}

// ---- side panel -----------------------------------------------------------------------
function setConnection(ok, text) {
  const c = document.getElementById('connection');
  c.className = ok ? 'ok' : 'bad';
  c.textContent = text;
}

function cell(text, cls) {
  const td = document.createElement('td');
  td.textContent = text;
  if (cls) td.className = cls;
  return td;
}

function fillTable(table, rows) {
  const body = table.tBodies[0] || table;
  body.replaceChildren(...rows.map((cells) => {
    const tr = document.createElement('tr');
    tr.append(...cells);
    return tr;
  }));
}

function kb(bytes) { return (bytes / 1024).toFixed(1) + ' kB'; }

function renderPanel() {
  const s = state.status, t = s.totals;
  fillTable(document.getElementById('totals'), [
    [cell('agents'), cell(t.agents, 'num'), cell('maps'), cell(t.maps, 'num')],
    [cell('keyframes'), cell(t.keyframes, 'num'), cell('map points'), cell(t.map_points, 'num')],
    [cell('fusions'), cell(t.fusions, 'num'), cell('loops'), cell(t.loops, 'num')],
    [cell('global BAs'), cell(t.global_bas, 'num'), cell('PR queue'), cell(s.queues.place_recognition, 'num')],
  ]);
  fillTable(document.getElementById('agents'), s.agents.map((a) => {
    const sw = cell('');
    sw.innerHTML = '<span class="swatch" style="background:#' + colourOf(a.id).toString(16).padStart(6, '0') + '"></span>';
    const name = a.name ? a.id + ' ' + a.name : String(a.id);
    const tracking = a.tracking !== undefined ? a.tracking + (a.alive === false ? ' (gone)' : '') : '-';
    return [sw, cell(name), cell(a.keyframes, 'num'), cell(a.map || '-'), cell(tracking), cell(a.queue ?? '-', 'num')];
  }));
  fillTable(document.getElementById('maps'), s.maps.map((m) =>
    [cell(m.id), cell(m.keyframes, 'num'), cell(m.map_points, 'num'), cell(m.agents.join(', '))]));
  const rows = [[cell('this page'), cell(kb(state.bytes), 'num')],
                [cell('view refresh'), cell(s.snapshot.refresh_ms.toFixed(1) + ' ms', 'num')],
                [cell('longest lock hold'), cell(s.snapshot.max_lock_hold_us.toFixed(0) + ' \u00b5s', 'num')]];
  for (const tp of (s.host.traffic || [])) rows.push([cell(tp.topic + ' ' + tp.direction), cell(kb(tp.bytes), 'num')]);
  if (s.host.frames_total) rows.push([cell('frames replayed'), cell(s.host.frames_done + ' / ' + s.host.frames_total, 'num')]);
  fillTable(document.getElementById('traffic'), rows);
  const list = document.getElementById('events');
  for (const e of state.events.slice(list.children.length)) {
    const li = document.createElement('li');
    li.className = e.kind;
    li.textContent = e.time_s.toFixed(1) + ' s ' + e.kind + ' agent ' + e.agent + ' map ' + e.map +
                     (e.other_map ? ' + ' + e.other_map : '') + (e.detail ? ': ' + e.detail : '');
    list.prepend(li);
  }
  const fusions = state.events.filter((e) => e.kind === 'fusion').length;
  const st = document.getElementById('view-status').dataset;
  Object.assign(st, {
    updates: state.updates, agents: t.agents, keyframes: state.keyframes.size, fusions, maps: t.maps,
    version: state.version, points: state.points.size, edges: state.edges.size, events: state.events.length,
    bytes: state.bytes, webgl: renderer ? 1 : 0, serverKeyframes: t.keyframes, serverFusions: t.fusions,
  });
}

// ---- controls -------------------------------------------------------------------------
document.getElementById('top-view').addEventListener('click', (ev) => {
  state.topView = !state.topView;
  ev.target.classList.toggle('on', state.topView);
  if (renderer) fitView();
});
document.getElementById('fit-view').addEventListener('click', () => { if (renderer) fitView(); });
document.getElementById('min-weight').addEventListener('change', (ev) => {
  const w = Math.max(0, Math.min(100000, parseInt(ev.target.value, 10) || 0));
  ev.target.value = w;
  state.minWeight = w;
  state.version = 0;  // the edge set depends on the weight: reload in full
});
document.getElementById('show-points').addEventListener('change', (ev) => {
  if (renderer) layers.points.visible = ev.target.checked;
});
// ?top=1 starts in the top view (screenshots, wall displays).
if (new URLSearchParams(location.search).get('top') === '1') {
  state.topView = true;
  document.getElementById('top-view').classList.add('on');
}

animate();
poll();
