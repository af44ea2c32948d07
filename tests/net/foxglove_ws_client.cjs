// SPDX-License-Identifier: Apache-2.0
// Connects to a Foxglove WebSocket server with Foxglove's own client (@foxglove/ws-protocol's
// FoxgloveClient on the ws package, installed by tools/setup into tools/node), subscribes to
// every advertised channel (or those named) and checks what arrives: serverInfo, the
// advertisement (a JSON Schema per channel), and messages that parse under their channel's
// schema (its required fields present) with times that never go back.
//
// usage: node foxglove_ws_client.cjs NODE_DIR URL COUNT [TOPIC...]
//   Waits for COUNT messages on each subscribed channel, prints one JSON line (serverInfo,
//   channels, counts, the last message per topic) and exits 0; exits 1 with a message on a
//   failed check, a close before the counts, or after 30 s.
// usage: node foxglove_ws_client.cjs NODE_DIR URL COUNT --hold SECONDS [TOPIC...]
//   The same, but reads on until SECONDS after the start before it prints and exits (a client
//   that keeps up, beside one under test).
// usage: node foxglove_ws_client.cjs NODE_DIR URL --refused
//   Exits 0 when the server refuses the connection (no serverInfo), 1 if it is served.
"use strict";
const path = require("node:path");
const { createRequire } = require("node:module");

const [nodeDir, url, countArg, ...rest] = process.argv.slice(2);
const holdS = rest[0] === "--hold" ? Number(rest[1]) : 0;
const topics = rest[0] === "--hold" ? rest.slice(2) : rest;
const startMs = Date.now();
const req = createRequire(path.join(path.resolve(nodeDir), "package.json"));
const { FoxgloveClient } = req("@foxglove/ws-protocol");
const WebSocket = req("ws");

function fail(msg) {
  console.error(`foxglove_ws_client: ${url}: ${msg}`);
  process.exit(1);
}

const refusedMode = countArg === "--refused";
const want = refusedMode ? 0 : Number(countArg);
const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const textDecoder = new TextDecoder();
let serverInfo;
const channels = new Map(); // subscription id -> channel
const required = new Map(); // channel id -> required fields of its schema
const counts = {};
const lastTime = {};
const last = {};
let done = false; // the summary is written: what still arrives until the exit is ignored

setTimeout(() => {
  if (refusedMode) fail("no refusal within 30 s");
  fail(`${30 + holdS} s and only ${JSON.stringify(counts)}`);
}, (30 + holdS) * 1000).unref();

client.on("error", (e) => {
  if (refusedMode || done) return;
  fail(`error: ${e?.message ?? e}`);
});
client.on("close", () => {
  if (done) return;
  if (refusedMode && !serverInfo) {
    console.log(JSON.stringify({ refused: true }));
    process.exit(0);
  }
  fail(`closed before the counts: ${JSON.stringify(counts)}`);
});
client.on("serverInfo", (info) => {
  if (refusedMode) fail("served although a refusal was expected");
  serverInfo = info;
});
client.on("status", (s) => fail(`status from the server: ${JSON.stringify(s)}`));
client.on("advertise", (advertised) => {
  if (!serverInfo) fail("advertise before serverInfo");
  for (const ch of advertised) {
    if (ch.schemaEncoding !== "jsonschema" || ch.encoding !== "json") {
      fail(`${ch.topic}: encoding ${ch.encoding} / ${ch.schemaEncoding}`);
    }
    let schema;
    try {
      schema = JSON.parse(ch.schema);
    } catch (e) {
      fail(`${ch.topic}: schema is not JSON: ${e.message}`);
    }
    if (schema.type !== "object") fail(`${ch.topic}: schema type ${schema.type}`);
    required.set(ch.id, schema.required ?? []);
    if (topics.length > 0 && !topics.includes(ch.topic)) continue;
    const sub = client.subscribe(ch.id);
    channels.set(sub, ch);
    counts[ch.topic] = 0;
  }
  for (const t of topics) if (!(t in counts)) fail(`${t} not advertised`);
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  if (done) return;
  const ch = channels.get(subscriptionId);
  if (!ch) fail(`message on unknown subscription ${subscriptionId}`);
  let msg;
  try {
    msg = JSON.parse(textDecoder.decode(data));
  } catch (e) {
    fail(`${ch.topic}: message is not JSON: ${e.message}`);
  }
  for (const key of required.get(ch.id)) {
    if (!(key in msg)) fail(`${ch.topic}: message lacks '${key}'`);
  }
  if (lastTime[ch.topic] !== undefined && timestamp < lastTime[ch.topic]) {
    fail(`${ch.topic}: time ${timestamp} after ${lastTime[ch.topic]}`);
  }
  lastTime[ch.topic] = timestamp;
  // The message as received, its long strings (padding, base64) by their length only.
  const brief = Object.fromEntries(
    Object.entries(msg).map(([k, v]) => [k, typeof v === "string" && v.length > 256 ? v.length : v]),
  );
  last[ch.topic] = { timestamp: timestamp.toString(), message: brief, bytes: data.byteLength };
  counts[ch.topic] += 1;
  if (Object.values(counts).every((n) => n >= want) && Date.now() - startMs >= holdS * 1000) {
    done = true;
    // Written, then exit: process.exit right after a write to a pipe can cut it short.
    process.stdout.write(
      JSON.stringify({
        serverInfo,
        channels: [...channels.values()].map((c) => ({
          id: c.id,
          topic: c.topic,
          schemaName: c.schemaName,
        })),
        counts,
        last,
      }) + "\n",
      () => process.exit(0),
    );
    client.close();
  }
});
