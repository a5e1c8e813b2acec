// A Foxglove WebSocket client (the npm package @foxglove/ws-protocol over `ws`), run by
// tests/cli/gateway_foxglove.rs against the gateway's Foxglove server. It prints one JSON
// object a line; the Rust test decodes and checks them.
//
//   node client.mjs URL CONFIG
//
// CONFIG (JSON): {
//   subscribe: topic whose messages are printed, count: how many,
//   publish: topic to advertise and write, schemaName, sampleHex: the CDR message to send,
//   watch: topic read until its message has watchHex at byte watchAt (the framework read
//          the sample), step: how many steps the step service makes while paused,
//   tf: the entities' poses topic whose first tfCount messages are printed (optional),
//   playback: true to drive the run with Foxglove's playback control requests
// }
// Every wait has its own deadline; the test's watchdog ends the process if it hangs anyway.

// The package is CommonJS for Node: its exports come as the default import.
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";
import { isPlaybackState, playbackControl, within } from "./playback.mjs";

const { FoxgloveClient } = wsProtocol;

const [url, configText] = process.argv.slice(2);
const cfg = JSON.parse(configText);
const print = (o) => console.log(JSON.stringify(o));
const fail = (why) => {
  print({ kind: "error", why: String(why) });
  process.exit(1);
};
const hex = (view) =>
  Buffer.from(view.buffer, view.byteOffset, view.byteLength).toString("hex");

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
// The package knows no playback control (Foxglove's newer capability): playback.mjs sends its
// requests as raw frames on the same socket and reads the answers from it.
client.on("error", (e) => {
  if (!isPlaybackState(e)) fail(e?.message ?? e);
});
const playback = playbackControl(ws);
client.on("close", () => print({ kind: "closed" }));
client.on("status", (s) => print({ kind: "status", level: s.level, message: s.message }));

let channels = new Map();
let services = new Map();
const advertised = new Promise((resolve) => client.on("advertise", (cs) => {
  for (const c of cs) channels.set(c.topic, c);
  resolve();
}));
const servicesAdvertised = new Promise((resolve) => client.on("advertiseServices", (ss) => {
  for (const s of ss) services.set(s.name, s);
  resolve();
}));
const serverInfo = new Promise((resolve) => client.on("serverInfo", resolve));

// Messages by subscription.
const handlers = new Map();
client.on("message", (m) => handlers.get(m.subscriptionId)?.(m));
let times = 0;
let lastTime = 0n;
client.on("time", (t) => {
  times += 1;
  lastTime = t.timestamp;
});

// Service calls: one at a time, answered by id.
let nextCall = 1;
const pending = new Map();
client.on("serviceCallResponse", (r) => {
  const text = new TextDecoder().decode(r.data);
  pending.get(r.callId)?.resolve(JSON.parse(text));
});
client.on("serviceCallFailure", (f) => pending.get(f.callId)?.reject(new Error(f.message)));
const call = (name, request) => {
  const service = services.get(name);
  if (!service) fail(`no service ${name}`);
  const callId = nextCall++;
  const answer = new Promise((resolve, reject) => pending.set(callId, { resolve, reject }));
  client.sendServiceCallRequest({
    serviceId: service.id,
    callId,
    encoding: "json",
    data: new TextEncoder().encode(JSON.stringify(request)),
  });
  return within(30000, `answer from ${name}`, answer);
};

const channel = (topic) => channels.get(topic) ?? fail(`no channel ${topic}`);

try {
  const info = await within(30000, "serverInfo", serverInfo);
  print({ kind: "serverInfo", capabilities: info.capabilities, protocol: ws.protocol,
          dataStartTime: info.dataStartTime, dataEndTime: info.dataEndTime });
  await within(30000, "advertise", advertised);
  await within(30000, "advertiseServices", servicesAdvertised);
  print({
    kind: "channels",
    channels: [...channels.values()].map((c) => ({
      topic: c.topic, encoding: c.encoding, schemaName: c.schemaName, schemaEncoding: c.schemaEncoding,
      schema: c.schema,
    })),
    services: [...services.keys()],
  });

  // 1. Messages of one set.
  const got = [];
  await within(60000, `${cfg.count} messages on ${cfg.subscribe}`, new Promise((resolve) => {
    const sub = client.subscribe(channel(cfg.subscribe).id);
    handlers.set(sub, (m) => {
      if (got.length < cfg.count) {
        got.push({ kind: "message", topic: cfg.subscribe, timestamp: m.timestamp.toString(), hex: hex(m.data) });
      }
      if (got.length === cfg.count) {
        client.unsubscribe(sub);
        handlers.delete(sub);
        resolve();
      }
    });
  }));
  got.forEach(print);

  // 1b. The entities' poses on /tf, when asked.
  if (cfg.tf) {
    const tfs = [];
    await within(60000, `${cfg.tfCount} messages on ${cfg.tf}`, new Promise((resolve) => {
      const sub = client.subscribe(channel(cfg.tf).id);
      handlers.set(sub, (m) => {
        if (tfs.length < cfg.tfCount) {
          tfs.push({ kind: "tf", timestamp: m.timestamp.toString(), hex: hex(m.data) });
        }
        if (tfs.length === cfg.tfCount) {
          client.unsubscribe(sub);
          handlers.delete(sub);
          resolve();
        }
      });
    }));
    tfs.forEach(print);
  }

  // 2. A sample published into a SUBSCRIBE set, until the framework is seen to read it.
  const sample = Buffer.from(cfg.sampleHex, "hex");
  const pub = client.advertise({ topic: cfg.publish, encoding: "cdr", schemaName: cfg.schemaName });
  let seen = null;
  const watch = client.subscribe(channel(cfg.watch).id);
  handlers.set(watch, (m) => {
    const h = hex(m.data);
    if (!seen && h.slice(cfg.watchAt * 2, cfg.watchAt * 2 + cfg.watchHex.length) === cfg.watchHex) {
      seen = { kind: "seen", topic: cfg.watch, hex: h, timestamp: m.timestamp.toString() };
    }
  });
  const deadline = Date.now() + 60000;
  while (!seen && Date.now() < deadline) {
    client.sendMessage(pub, sample);
    await new Promise((r) => setTimeout(r, 50));
  }
  if (!seen) fail(`${cfg.watch} never showed the published value`);
  print(seen);
  client.unsubscribe(watch);
  client.unadvertise(pub);

  // 3. The run paused, stepped, resumed through the services.
  for (const [name, request] of [["/tutti/pause", {}], ["/tutti/step", { n: cfg.step }], ["/tutti/state", {}], ["/tutti/resume", {}]]) {
    print({ kind: "service", name, status: await call(name, request) });
  }

  // 3b. Foxglove's playback controls: pause, play at twice the speed, a seek (refused live),
  // then back to real time.
  if (cfg.playback) {
    for (const [command, speed, seek, id] of [[1, 1, null, "pause"], [0, 2, null, "play2x"], [0, 2, 0, "seek"], [0, 1, null, "play1x"]]) {
      const state = await playback(command, speed, seek, id);
      print({ kind: "playback", request: id, ...state, run: await call("/tutti/state", {}) });
    }
  }

  // 4. The connection graph.
  const graph = new Promise((resolve) => client.on("connectionGraphUpdate", resolve));
  client.subscribeConnectionGraph();
  const g = await within(30000, "connectionGraphUpdate", graph);
  print({ kind: "graph", publishedTopics: g.publishedTopics, subscribedTopics: g.subscribedTopics, advertisedServices: g.advertisedServices });

  print({ kind: "time", count: times, last: lastTime.toString() });
  print({ kind: "done" });
  client.close();
  process.exit(0);
} catch (e) {
  fail(e?.message ?? e);
}
