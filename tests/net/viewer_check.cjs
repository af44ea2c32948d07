// SPDX-License-Identifier: Apache-2.0
// Opens wallar's live viewer page in headless Chromium (Debian's chromium, driven over the
// DevTools protocol with the ws package from tools/node), waits until the page has drawn the
// map, the walls, a pose and both camera images, takes a screenshot, and checks that the
// screenshot holds each surface's colour (blended over the background, as the page draws it)
// where the page says the surface's triangles fall on the screen.
//
// usage: node viewer_check.cjs NODE_DIR URL SCREENSHOT.png
//   Prints one JSON line (what the page drew, samples checked and matched per surface) and
//   exits 0 when at least 60 % of the samples match (and there are some); 1 otherwise, or
//   when the page has not drawn everything within 90 s.
"use strict";
const path = require("node:path");
const fs = require("node:fs");
const os = require("node:os");
const { spawn } = require("node:child_process");
const { createRequire } = require("node:module");

const [nodeDir, url, screenshot] = process.argv.slice(2);
const req = createRequire(path.join(path.resolve(nodeDir), "package.json"));
const WebSocket = req("ws");

const profile = fs.mkdtempSync(path.join(os.tmpdir(), "wallar-viewer-"));
const browser = spawn(
  process.env.CHROMIUM ?? "chromium",
  [
    "--headless=new",
    "--no-sandbox",
    "--no-first-run",
    "--no-default-browser-check",
    "--hide-scrollbars",
    "--mute-audio",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--window-size=1280,800",
    "--remote-debugging-port=0",
    `--user-data-dir=${profile}`,
    "about:blank",
  ],
  { stdio: ["ignore", "ignore", "pipe"] },
);
let finished = false;
function done(code, line) {
  if (finished) return;
  finished = true;
  if (line) (code === 0 ? process.stdout : process.stderr).write(line + "\n");
  browser.kill("SIGKILL");
  fs.rmSync(profile, { recursive: true, force: true });
  process.exitCode = code;
  setTimeout(() => process.exit(code), 200).unref();
}
const fail = (msg) => done(1, `viewer_check: ${url}: ${msg}`);
setTimeout(() => fail("90 s and the page has not drawn everything"), 90000).unref();
browser.on("exit", (code) => fail(`chromium exited (${code}) before the check ended`));

let stderr = "";
browser.stderr.on("data", (d) => {
  stderr += d.toString();
  const m = stderr.match(/DevTools listening on (ws:\/\/\S+)/);
  if (m && !started) {
    started = true;
    run(m[1]).catch((e) => fail(e.message ?? String(e)));
  }
});
let started = false;

async function run(browserUrl) {
  const ws = new WebSocket(browserUrl, { perMessageDeflate: false, maxPayload: 256 << 20 });
  await new Promise((ok, ko) => {
    ws.once("open", ok);
    ws.once("error", ko);
  });
  let nextId = 1;
  const pending = new Map();
  ws.on("message", (data) => {
    const msg = JSON.parse(data.toString());
    const p = pending.get(msg.id);
    if (!p) return;
    pending.delete(msg.id);
    if (msg.error) p.ko(new Error(`${p.method}: ${msg.error.message}`));
    else p.ok(msg.result);
  });
  const send = (method, params = {}, sessionId) =>
    new Promise((ok, ko) => {
      const id = nextId++;
      pending.set(id, { ok, ko, method });
      ws.send(JSON.stringify({ id, method, params, sessionId }));
    });

  const { targetId } = await send("Target.createTarget", { url: "about:blank" });
  const { sessionId } = await send("Target.attachToTarget", { targetId, flatten: true });
  const page = (method, params) => send(method, params, sessionId);
  await page("Page.enable");
  await page("Emulation.setDeviceMetricsOverride", {
    width: 1280,
    height: 800,
    deviceScaleFactor: 1,
    mobile: false,
  });
  await page("Page.navigate", { url });
  const evaluate = async (expression) => {
    const r = await page("Runtime.evaluate", { expression, awaitPromise: true, returnByValue: true });
    if (r.exceptionDetails) throw new Error(`page: ${r.exceptionDetails.exception?.description}`);
    return r.result.value;
  };

  // Everything drawn, and some frames since the walls came.
  let state = null;
  let framesAtWalls = -1;
  for (;;) {
    state = await evaluate("window.wallarViewer ? JSON.stringify(window.wallarViewer.state) : ''");
    state = state ? JSON.parse(state) : null;
    if (state && state.walls > 0 && framesAtWalls < 0) framesAtWalls = state.frames;
    if (
      state &&
      state.map > 0 &&
      state.walls > 0 &&
      state.poses > 0 &&
      state.images >= 2 &&
      state.fitted &&
      state.frames > framesAtWalls + 20
    ) {
      break;
    }
    await new Promise((r) => setTimeout(r, 250));
  }
  const samples = JSON.parse(await evaluate("JSON.stringify(window.wallarViewer.wallSamples())"));
  const shot = await page("Page.captureScreenshot", { format: "png" });
  fs.writeFileSync(screenshot, Buffer.from(shot.data, "base64"));
  // The screenshot's pixels at the samples, decoded by the browser itself.
  const pixels = await evaluate(`(async () => {
    const img = new Image();
    img.src = "data:image/png;base64,${shot.data}";
    await img.decode();
    const c = document.createElement("canvas");
    c.width = img.width;
    c.height = img.height;
    const g = c.getContext("2d");
    g.drawImage(img, 0, 0);
    const pts = ${JSON.stringify(samples.map((s) => [Math.round(s.x), Math.round(s.y)]))};
    return JSON.stringify(pts.map(([x, y]) => Array.from(g.getImageData(x, y, 1, 1).data.slice(0, 3))));
  })()`);
  const got = JSON.parse(pixels);
  const per = {};
  let matched = 0;
  samples.forEach((s, i) => {
    const ok = s.rgb.every((v, k) => Math.abs(v - got[i][k]) <= 24);
    per[s.surface] ??= { samples: 0, matched: 0, expected: s.rgb, example: got[i] };
    per[s.surface].samples += 1;
    if (ok) {
      per[s.surface].matched += 1;
      matched += 1;
    }
  });
  const summary = { state, samples: samples.length, matched, surfaces: per };
  if (samples.length === 0) return fail(`no surface in view: ${JSON.stringify(summary)}`);
  if (matched < 0.6 * samples.length) return fail(`walls not drawn: ${JSON.stringify(summary)}`);
  done(0, JSON.stringify(summary));
}
