// A Foxglove WebSocket client as older viewers are: npm's `@foxglove/ws-protocol` client over npm
// `ws`, offering the subprotocol they offer (`foxglove.websocket.v1`). It decodes the CDR it
// needs by hand, from the ROS 2 message definitions, independent of sqscan's encoder.
//
//   node ws_protocol_client.js URL TIMEOUT_S all
//     subscribes to every channel once all seven are advertised, prints "subscribed", then prints
//     one JSON object once it has a point cloud and a detection array.
//   node ws_protocol_client.js URL TIMEOUT_S tf_static
//     subscribes to /tf_static alone, prints "subscribed", then prints the first message it gets
//     and how long after subscribing it came.
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, timeoutS, mode] = process.argv.slice(2);
setTimeout(() => {
  console.error(`no answer within ${timeoutS} s`);
  process.exit(2);
}, 1000 * Number(timeoutS));

// A CDR (little-endian) reader: alignment counts from after the 4-byte encapsulation header.
class Cdr {
  constructor(view) {
    this.v = view;
    this.o = 4;
  }
  align(n) {
    this.o = 4 + Math.ceil((this.o - 4) / n) * n;
  }
  u32() {
    this.align(4);
    const x = this.v.getUint32(this.o, true);
    this.o += 4;
    return x;
  }
  i32() {
    this.align(4);
    const x = this.v.getInt32(this.o, true);
    this.o += 4;
    return x;
  }
  f64() {
    this.align(8);
    const x = this.v.getFloat64(this.o, true);
    this.o += 8;
    return x;
  }
  string() {
    const n = this.u32();
    const bytes = new Uint8Array(this.v.buffer, this.v.byteOffset + this.o, Math.max(n - 1, 0));
    this.o += n;
    return Buffer.from(bytes).toString("utf8");
  }
  header() {
    const sec = this.i32();
    const nanosec = this.u32();
    return { stamp: sec + 1e-9 * nanosec, frame: this.string() };
  }
}

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const out = { subprotocol: null, server_name: null, topics: [], points: null, detections: null };
const channels = new Map();
const topicOf = new Map();
let subscribedAt = null;

client.on("error", (e) => console.error(`client error: ${e}`));
client.on("open", () => {
  out.subprotocol = ws.protocol;
});
client.on("serverInfo", (info) => {
  out.server_name = info.name;
});
client.on("advertise", (list) => {
  for (const c of list) channels.set(c.id, c);
  if (subscribedAt !== null || channels.size < 7) return;
  for (const c of channels.values()) {
    if (mode === "tf_static" && c.topic !== "/tf_static") continue;
    topicOf.set(client.subscribe(c.id), c.topic);
  }
  out.topics = [...channels.values()].map((c) => [c.topic, c.schemaName, c.encoding]).sort();
  subscribedAt = Date.now();
  console.log("subscribed");
});
client.on("message", ({ subscriptionId, data }) => {
  const topic = topicOf.get(subscriptionId);
  const r = new Cdr(data);
  if (mode === "tf_static") {
    if (topic !== "/tf_static") return;
    const transforms = [];
    for (let k = r.u32(); k > 0; k--) {
      const header = r.header();
      const child = r.string();
      const t = [r.f64(), r.f64(), r.f64()];
      const q = [r.f64(), r.f64(), r.f64(), r.f64()];
      transforms.push({ parent: header.frame, child, translation: t, rotation: q });
    }
    console.log(JSON.stringify({ ...out, tf_static: transforms, after_ms: Date.now() - subscribedAt }));
    process.exit(0);
  }
  if (topic === "/sqscan/points" && out.points === null) {
    const header = r.header();
    out.points = { frame: header.frame, height: r.u32(), width: r.u32(), bytes: data.byteLength };
  } else if (topic === "/sqscan/detections" && out.detections === null) {
    const header = r.header();
    out.detections = { frame: header.frame, count: r.u32() };
  }
  if (out.points !== null && out.detections !== null) {
    console.log(JSON.stringify(out));
    process.exit(0);
  }
});
