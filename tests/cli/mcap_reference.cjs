// SPDX-License-Identifier: Apache-2.0
// Reads an MCAP file with Foxglove's own reader (@mcap/core, with @mcap/support's zstd and lz4)
// and checks what cli.mcap asserts of wallar's files: the footer, summary and its CRC, the
// statistics, every chunk through its chunk index and message indexes (CRCs validated), the
// same messages from a front-to-back stream read, each topic's count, times that increase, and
// messages that parse under their channel's JSON schema's required fields, and whole camera
// calibrations beside the images.
//
// usage: node mcap_reference.cjs NODE_DIR FILE TOPIC=COUNT...
//        node mcap_reference.cjs NODE_DIR --stream FILE...
// Prints one JSON line of what it read; exits 1 with a message on the first failed check.
// --stream: files that may be cut short, each read front to back as far as it goes; prints,
// a line per file, the message count per topic of the complete records (what a reader can
// recover).
"use strict";
const path = require("node:path");
const fs = require("node:fs");
const { createRequire } = require("node:module");

const [nodeDir, file, ...expected] = process.argv.slice(2);
const req = createRequire(path.join(path.resolve(nodeDir), "package.json"));
const { McapIndexedReader, McapStreamReader } = req("@mcap/core");
const { loadDecompressHandlers } = req("@mcap/support");

function fail(msg) {
  console.error(`mcap_reference: ${file}: ${msg}`);
  process.exit(1);
}

async function streamCounts(files) {
  const decompressHandlers = await loadDecompressHandlers();
  for (const f of files) {
    const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
    stream.append(new Uint8Array(fs.readFileSync(f)));
    const topics = new Map();
    const counts = {};
    for (let r; (r = stream.nextRecord()); ) {
      if (r.type === "Channel") {
        topics.set(r.id, r.topic);
        counts[r.topic] ??= 0;
      }
      if (r.type === "Message") counts[topics.get(r.channelId)] += 1;
    }
    console.log(JSON.stringify({ file: f, complete: stream.done(), counts }));
  }
}

async function main() {
  if (file === "--stream") return streamCounts(expected);
  const decompressHandlers = await loadDecompressHandlers();
  const fd = await fs.promises.open(file, "r");
  const size = (await fd.stat()).size;
  const readable = {
    size: async () => BigInt(size),
    read: async (offset, length) => {
      const buf = Buffer.alloc(Number(length));
      await fd.read(buf, 0, Number(length), Number(offset));
      return new Uint8Array(buf.buffer, buf.byteOffset, buf.byteLength);
    },
  };
  // Indexed: footer, summary (CRC checked), chunk indexes -> message indexes -> messages.
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  if (!reader.statistics) fail("no Statistics record in the summary");
  const topicOf = new Map([...reader.channelsById.values()].map((c) => [c.id, c.topic]));
  const counts = {};
  const last = {};
  const required = {};
  const schemaNames = {};
  const pointClouds = {};
  const scenes = {};
  const calibrations = {};
  for (const ch of reader.channelsById.values()) {
    const schema = reader.schemasById.get(ch.schemaId);
    schemaNames[ch.topic] = schema?.name;
    if (!schema || schema.encoding !== "jsonschema") fail(`${ch.topic}: no JSON schema`);
    required[ch.topic] = JSON.parse(new TextDecoder().decode(schema.data)).required ?? [];
    counts[ch.topic] = 0;
  }
  let total = 0;
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const topic = topicOf.get(m.channelId);
    if (last[topic] !== undefined && m.logTime <= last[topic]) {
      fail(`${topic}: log time ${m.logTime} does not increase (after ${last[topic]})`);
    }
    last[topic] = m.logTime;
    const msg = JSON.parse(new TextDecoder().decode(m.data));
    for (const key of required[topic]) {
      if (!(key in msg)) fail(`${topic} message at ${m.logTime} lacks '${key}'`);
    }
    // A message's own time is its log time (SceneUpdate carries it on each entity).
    for (const ts of [msg.timestamp, ...(msg.entities ?? []).map((e) => e.timestamp)]) {
      if (ts === undefined) continue;
      const stamp = BigInt(ts.sec) * 1000000000n + BigInt(ts.nsec);
      if (stamp !== m.logTime) fail(`${topic}: timestamp ${stamp} != log time ${m.logTime}`);
    }
    if (schemaNames[topic] === "foxglove.PointCloud") {
      const bytes = Buffer.from(msg.data, "base64").length;
      if (bytes % msg.point_stride !== 0 || msg.fields.length === 0) {
        fail(`${topic}: ${bytes} bytes of points is not a whole number of ${msg.point_stride}`);
      }
      pointClouds[topic] = bytes / msg.point_stride;
    }
    if (schemaNames[topic] === "foxglove.CameraCalibration") {
      // Beside its image topic, in its frame, with whole matrices of finite numbers.
      const cam = topic.replace(/\/calibration$/, "");
      if (cam === topic || msg.frame_id !== cam.slice(1)) fail(`${topic}: frame_id ${msg.frame_id}`);
      const sizes = { K: 9, R: 9, P: 12 };
      for (const [key, n] of Object.entries(sizes)) {
        if (msg[key].length !== n || !msg[key].every(Number.isFinite)) fail(`${topic}: ${key}`);
      }
      const d = { plumb_bob: 5, kannala_brandt: 4 }[msg.distortion_model];
      if (d === undefined || msg.D.length !== d) fail(`${topic}: D for ${msg.distortion_model}`);
      if (!(msg.width > 0 && msg.height > 0 && msg.K[0] > 0 && msg.K[8] === 1)) {
        fail(`${topic}: ${msg.width}x${msg.height}, K ${msg.K}`);
      }
      calibrations[topic] = { width: msg.width, height: msg.height, fx: msg.K[0], D: msg.D };
    }
    if (schemaNames[topic] === "foxglove.SceneUpdate") {
      for (const e of msg.entities) {
        for (const t of e.triangles) {
          if (t.points.length === 0 || t.points.length % 3 !== 0) fail(`${e.id}: not triangles`);
        }
      }
      scenes[topic] = msg.entities.map((e) => e.id);
    }
    counts[topic] += 1;
    total += 1;
  }
  const stats = reader.statistics;
  if (BigInt(total) !== stats.messageCount) {
    fail(`read ${total} messages through the indexes, statistics say ${stats.messageCount}`);
  }
  for (const [id, n] of stats.channelMessageCounts) {
    if (BigInt(counts[topicOf.get(id)]) !== n) {
      fail(`${topicOf.get(id)}: ${counts[topicOf.get(id)]} messages, statistics say ${n}`);
    }
  }
  if (reader.chunkIndexes.length !== stats.chunkCount) fail("chunk index count != statistics");
  // Streamed front to back: every record parses, the data section's CRC and each chunk's hold.
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(new Uint8Array(fs.readFileSync(file)));
  let streamed = 0;
  let dataEnd = false;
  for (let r; (r = stream.nextRecord()); ) {
    if (r.type === "Message") streamed += 1;
    if (r.type === "DataEnd") dataEnd = true;
  }
  if (!stream.done()) fail("the stream reader did not reach the trailing magic");
  if (!dataEnd) fail("no Data End record");
  if (streamed !== total) fail(`streamed ${streamed} messages, indexed ${total}`);
  for (const e of expected) {
    const [topic, n] = e.split("=");
    if (counts[topic] !== Number(n)) fail(`${topic}: ${counts[topic]} messages, expected ${n}`);
  }
  let metadata = 0;
  for await (const _ of reader.readMetadata()) metadata += 1;
  console.log(
    JSON.stringify({
      messages: total,
      chunks: reader.chunkIndexes.length,
      metadata,
      counts,
      points: pointClouds,
      entities: scenes,
      calibrations,
      library: reader.header.library,
    }),
  );
  await fd.close();
}

main().catch((e) => fail(e.message ?? String(e)));
