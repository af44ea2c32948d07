// SPDX-License-Identifier: Apache-2.0
// wallar's live viewer: a client of the live server's Foxglove WebSocket protocol
// (foxglove.websocket.v1) on the page's own port. It subscribes to every channel and draws the
// map (/map), walls, floor and ceiling (/walls), the trajectory (/trajectory) and the head's
// camera frustum (/tf) with three.js, both camera images (/cam0, /cam1), the stats (/stats)
// and the log (/log). The scene is shown in the frame "up" (z against gravity) once the
// firmware has gravity. window.wallarViewer tells a test what was drawn.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const BACKGROUND = 0x1e1e1e;
const WALL_OPACITY = 0.5;

const container = document.getElementById("scene");
const statusLine = document.getElementById("status");
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setClearColor(BACKGROUND);
container.appendChild(renderer.domElement);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(60, 1, 0.05, 500);
camera.up.set(0, 0, 1);
camera.position.set(-4, -4, 3);
const controls = new OrbitControls(camera, renderer.domElement);
scene.add(new THREE.AxesHelper(0.3));

// Everything the firmware sends is in "world" (the tracker's); this group is world in "up".
const world = new THREE.Group();
world.matrixAutoUpdate = false;
scene.add(world);

const mapGeometry = new THREE.BufferGeometry();
const map = new THREE.Points(
  mapGeometry,
  new THREE.PointsMaterial({ size: 3, sizeAttenuation: false, vertexColors: true }),
);
map.frustumCulled = false;
world.add(map);

const path = new THREE.Line(
  new THREE.BufferGeometry(),
  new THREE.LineBasicMaterial({ color: 0x4ec9ff }),
);
path.frustumCulled = false;
world.add(path);

// The head: cam0's viewing pyramid (z forward, 0.25 m deep).
const frustum = (() => {
  const w = 0.15, h = 0.1, d = 0.25;
  const c = [
    [0, 0, 0], [-w, -h, d], [0, 0, 0], [w, -h, d], [0, 0, 0], [w, h, d], [0, 0, 0], [-w, h, d],
    [-w, -h, d], [w, -h, d], [w, -h, d], [w, h, d], [w, h, d], [-w, h, d], [-w, h, d], [-w, -h, d],
  ].flat();
  const g = new THREE.BufferGeometry();
  g.setAttribute("position", new THREE.Float32BufferAttribute(c, 3));
  const f = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: 0xffffff }));
  f.matrixAutoUpdate = false;
  f.visible = false;
  return f;
})();
world.add(frustum);

const surfaces = new Map(); // entity id -> { group, color, opacity, points }
const state = {
  connected: false,
  channels: 0,
  messages: 0,
  map: 0,
  walls: 0,
  poses: 0,
  images: 0,
  frames: 0,
  fitted: false,
};

function resize() {
  const w = container.clientWidth, h = container.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);
resize();

function matrixOf(t) {
  const q = t.rotation ?? t.orientation;
  const p = t.translation ?? t.position;
  return new THREE.Matrix4().compose(
    new THREE.Vector3(p.x, p.y, p.z),
    new THREE.Quaternion(q.x, q.y, q.z, q.w),
    new THREE.Vector3(1, 1, 1),
  );
}

// Foxglove's colours are sRGB; three.js works in linear sRGB and converts on output.
const srgbToLinear = (c) => (c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);
const colorOf = (c) => new THREE.Color().setRGB(c.r, c.g, c.b, THREE.SRGBColorSpace);

function base64Bytes(b64) {
  const s = atob(b64);
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; ++i) out[i] = s.charCodeAt(i);
  return out;
}

// The camera once, on the first map: from behind and above its bulk (the median point, the
// radius that holds 90 % of the points: a few far points do not shrink the view).
function fitTo(points) {
  const n = points.count;
  const p = [];
  for (let i = 0; i < n; ++i) {
    p.push(new THREE.Vector3().fromBufferAttribute(points, i).applyMatrix4(world.matrix));
  }
  const median = (k) => p.map((v) => v.getComponent(k)).sort((a, b) => a - b)[Math.floor(n / 2)];
  const centre = new THREE.Vector3(median(0), median(1), median(2));
  const d = p.map((v) => v.distanceTo(centre)).sort((a, b) => a - b);
  const r = Math.max(d[Math.floor(0.9 * (n - 1))], 0.5);
  controls.target.copy(centre);
  camera.position.copy(centre).add(new THREE.Vector3(-1.8 * r, -1.8 * r, 1.6 * r));
  camera.near = r / 100;
  camera.far = r * 50;
  camera.updateProjectionMatrix();
  controls.update();
  state.fitted = true;
}

const handlers = {
  "/tf": (m) => {
    const tf = new Map(m.transforms.map((t) => [`${t.parent_frame_id}>${t.child_frame_id}`, t]));
    const up = tf.get("up>world");
    if (up) {
      world.matrix.copy(matrixOf(up));
      world.matrixWorldNeedsUpdate = true;
    }
    const body = tf.get("world>body"), cam0 = tf.get("body>cam0");
    if (body && cam0) {
      frustum.matrix.copy(matrixOf(body).multiply(matrixOf(cam0)));
      frustum.matrixWorldNeedsUpdate = true;
      frustum.visible = true;
    }
    state.poses += 1;
  },
  "/map": (m) => {
    const bytes = base64Bytes(m.data);
    const stride = m.point_stride / 4;
    const f = new Float32Array(bytes.buffer, 0, Math.floor(bytes.length / 4));
    const n = Math.floor(f.length / stride);
    const pos = new Float32Array(3 * n), col = new Float32Array(3 * n);
    const offset = Object.fromEntries(m.fields.map((x) => [x.name, x.offset / 4]));
    for (let i = 0; i < n; ++i) {
      const b = i * stride;
      pos[3 * i] = f[b + offset.x];
      pos[3 * i + 1] = f[b + offset.y];
      pos[3 * i + 2] = f[b + offset.z];
      col[3 * i] = srgbToLinear(f[b + (offset.red ?? 0)]);
      col[3 * i + 1] = srgbToLinear(f[b + (offset.green ?? 0)]);
      col[3 * i + 2] = srgbToLinear(f[b + (offset.blue ?? 0)]);
    }
    mapGeometry.setAttribute("position", new THREE.BufferAttribute(pos, 3));
    mapGeometry.setAttribute("color", new THREE.BufferAttribute(col, 3));
    mapGeometry.computeBoundingSphere();
    state.map = n;
    if (!state.fitted && n > 0) fitTo(mapGeometry.getAttribute("position"));
  },
  "/walls": (m) => {
    if ((m.deletions ?? []).some((d) => d.type === 1)) {
      for (const s of surfaces.values()) world.remove(s.group);
      surfaces.clear();
    }
    for (const e of m.entities ?? []) {
      const old = surfaces.get(e.id);
      if (old) world.remove(old.group);
      const group = new THREE.Group();
      let color = null, points = [];
      for (const t of e.triangles ?? []) {
        points = t.points.map((p) => new THREE.Vector3(p.x, p.y, p.z));
        const g = new THREE.BufferGeometry().setFromPoints(points);
        color = colorOf(t.color);
        const mesh = new THREE.Mesh(
          g,
          new THREE.MeshBasicMaterial({
            color,
            transparent: true,
            opacity: WALL_OPACITY,
            side: THREE.DoubleSide,
            depthWrite: false,
          }),
        );
        mesh.userData.surface = e.id;
        group.add(mesh);
      }
      for (const l of e.lines ?? []) {
        const pts = l.points.map((p) => new THREE.Vector3(p.x, p.y, p.z));
        group.add(
          new THREE.LineLoop(
            new THREE.BufferGeometry().setFromPoints(pts),
            new THREE.LineBasicMaterial({ color: colorOf(l.color) }),
          ),
        );
      }
      world.add(group);
      surfaces.set(e.id, { group, color, points });
    }
    state.walls = surfaces.size;
  },
  "/trajectory": (m) => {
    const pts = m.poses.map((p) => new THREE.Vector3(p.position.x, p.position.y, p.position.z));
    path.geometry.dispose();
    path.geometry = new THREE.BufferGeometry().setFromPoints(pts);
  },
  "/cam0": (m) => showImage("cam0", m),
  "/cam1": (m) => showImage("cam1", m),
  "/stats": (m) => showStats(m),
  "/log": (m) => {
    const div = document.createElement("div");
    if (m.level >= 3) div.className = "warn";
    div.textContent = m.message;
    const log = document.getElementById("log");
    log.prepend(div);
    while (log.childElementCount > 200) log.lastChild.remove();
  },
};

function showImage(id, m) {
  document.getElementById(id).src = `data:image/${m.format};base64,${m.data}`;
  state.images += 1;
}

function table(id, rows, columns) {
  const t = document.getElementById(id);
  const head = `<tr>${columns.map(([, h]) => `<th>${h}</th>`).join("")}</tr>`;
  const fmt = (v) => (typeof v === "number" && !Number.isInteger(v) ? v.toFixed(2) : v ?? "");
  t.innerHTML =
    head +
    rows.map((r) => `<tr>${columns.map(([k]) => `<td>${fmt(r[k])}</td>`).join("")}</tr>`).join("");
}

function showStats(m) {
  table("stages", m.stages, [
    ["name", "stage"], ["p50_ms", "p50 ms"], ["p99_ms", "p99 ms"], ["max_ms", "max ms"],
    ["misses", "misses"],
  ]);
  table("threads", m.threads, [
    ["name", "thread"], ["policy", "policy"], ["cpu_percent", "cpu %"], ["misses", "misses"],
  ]);
  table("live", Object.entries(m.live ?? {}).map(([k, v]) => ({ k, v })), [["k", ""], ["v", ""]]);
}

// Foxglove's WebSocket protocol: serverInfo, advertise, subscribe, binary message data.
const textDecoder = new TextDecoder();
const topics = new Map(); // subscription id -> topic
function connect() {
  const token = new URLSearchParams(location.search).get("token");
  const url = `ws://${location.host}/${token ? `?token=${encodeURIComponent(token)}` : ""}`;
  const ws = new WebSocket(url, ["foxglove.websocket.v1"]);
  ws.binaryType = "arraybuffer";
  ws.onopen = () => {
    state.connected = true;
    statusLine.textContent = `connected to ${location.host}`;
  };
  ws.onclose = () => {
    state.connected = false;
    statusLine.textContent = "disconnected: retrying...";
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === "string") {
      const msg = JSON.parse(ev.data);
      if (msg.op === "advertise") {
        const subscriptions = msg.channels.map((c, i) => {
          topics.set(i + 1, c.topic);
          return { id: i + 1, channelId: c.id };
        });
        state.channels = subscriptions.length;
        ws.send(JSON.stringify({ op: "subscribe", subscriptions }));
      } else if (msg.op === "status") {
        statusLine.textContent = `server: ${msg.message}`;
      }
      return;
    }
    const view = new DataView(ev.data);
    if (view.getUint8(0) !== 1) return; // message data only
    const topic = topics.get(view.getUint32(1, true));
    const handler = handlers[topic];
    if (!handler) return;
    handler(JSON.parse(textDecoder.decode(new Uint8Array(ev.data, 13))));
    state.messages += 1;
  };
}
connect();

function animate() {
  requestAnimationFrame(animate);
  controls.update();
  renderer.render(scene, camera);
  state.frames += 1;
}
animate();

// For tests: what was drawn, and where each surface falls on the canvas (samples of its
// triangles projected to CSS pixels, with the colour expected there: the surface's blended
// over the background, where it is the only surface the ray meets). Blending happens on the
// output's sRGB values (the default framebuffer).
window.wallarViewer = {
  state,
  wallSamples() {
    scene.updateMatrixWorld(true);
    const rect = renderer.domElement.getBoundingClientRect();
    const srgb = (c) => {
      const o = {};
      c.getRGB(o, THREE.SRGBColorSpace);
      return [o.r, o.g, o.b];
    };
    const bg = srgb(new THREE.Color(BACKGROUND));
    const meshes = [];
    for (const s of surfaces.values()) s.group.traverse((o) => o.isMesh && meshes.push(o));
    const raycaster = new THREE.Raycaster();
    const out = [];
    for (const [id, s] of surfaces) {
      if (!s.color || s.points.length < 3) continue;
      const wall = srgb(s.color);
      const expected = bg.map((v, k) => v + (wall[k] - v) * WALL_OPACITY);
      for (let t = 0; t + 2 < s.points.length; t += 3) {
        for (const [a, b] of [[1 / 3, 1 / 3], [0.6, 0.2], [0.2, 0.6], [0.2, 0.2]]) {
          const p = new THREE.Vector3()
            .addScaledVector(s.points[t], 1 - a - b)
            .addScaledVector(s.points[t + 1], a)
            .addScaledVector(s.points[t + 2], b)
            .applyMatrix4(world.matrixWorld);
          const ndc = p.clone().project(camera);
          if (Math.abs(ndc.x) > 0.95 || Math.abs(ndc.y) > 0.95 || ndc.z > 1) continue;
          raycaster.setFromCamera(new THREE.Vector2(ndc.x, ndc.y), camera);
          const hits = raycaster.intersectObjects(meshes, false);
          if (hits.length !== 1) continue; // another surface in front or behind blends in
          out.push({
            surface: id,
            x: rect.left + ((ndc.x + 1) / 2) * rect.width,
            y: rect.top + ((1 - ndc.y) / 2) * rect.height,
            rgb: expected.map((v) => Math.round(v * 255)),
          });
        }
      }
    }
    return out;
  },
};
