// Foxglove's playback controls on a replay (the npm package @foxglove/ws-protocol over `ws`),
// run by tests/cli/gateway_foxglove.rs against `tutti replay --gateway`. The package has no
// playback control: its requests go as raw frames on the client's socket, and the server's
// Playback State frames (opcode 5) are read from the socket. Prints one JSON object a line.
//
//   node replay.mjs URL TOPIC SEEK_NS [TF]
//
// With TF (the entities' poses topic), its first 10 messages before the seek are printed too.
// Reads 20 messages of TOPIC (and on, until one is stamped after twice SEEK_NS), pauses, seeks
// back to SEEK_NS (staying paused), plays, and reads 20 more. Every wait has its own deadline; the test's watchdog ends the process if it hangs.
import wsProtocol from "@foxglove/ws-protocol";
import WebSocket from "ws";
import { isPlaybackState, playbackControl, within } from "./playback.mjs";

const { FoxgloveClient } = wsProtocol;
const [url, topic, seekText, tfTopic] = process.argv.slice(2);
const print = (o) => console.log(JSON.stringify(o));
const fail = (why) => {
  print({ kind: "error", why: String(why) });
  process.exit(1);
};

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
client.on("error", (e) => {
  if (!isPlaybackState(e)) fail(e?.message ?? e);
});
client.on("status", (s) => print({ kind: "status", level: s.level, message: s.message }));
const serverInfo = new Promise((resolve) => client.on("serverInfo", resolve));
const channels = new Map();
const advertised = new Promise((resolve) => client.on("advertise", (cs) => {
  for (const c of cs) channels.set(c.topic, c);
  resolve();
}));

const playback = playbackControl(ws);

let phase = "before";
let counts = { before: 0, after: 0 };
let done = null;
const seekNs = BigInt(seekText);
let tfSub = null;
let tfCount = 0;
const hex = (view) => Buffer.from(view.buffer, view.byteOffset, view.byteLength).toString("hex");
client.on("message", (m) => {
  if (m.subscriptionId === tfSub) {
    if (phase === "before" && tfCount < 10) {
      tfCount += 1;
      print({ kind: "tf", timestamp: m.timestamp.toString(), hex: hex(m.data) });
    }
    return;
  }
  if (phase === "paused" || counts[phase] >= 20) return;
  print({ kind: "message", phase, timestamp: m.timestamp.toString() });
  // Before the seek, on until the run is well past the time sought.
  if (phase === "after" || m.timestamp > 2n * seekNs) counts[phase] += 1;
  if (counts[phase] === 20) done?.();
});
const twenty = (what) => within(60000, `20 messages ${what}`, new Promise((resolve) => { done = resolve; }));

try {
  const info = await within(30000, "serverInfo", serverInfo);
  print({ kind: "serverInfo", capabilities: info.capabilities, dataStartTime: info.dataStartTime, dataEndTime: info.dataEndTime });
  await within(30000, "advertise", advertised);
  const channel = channels.get(topic) ?? fail(`no channel ${topic}`);
  const first = twenty("before the seek");
  if (tfTopic) tfSub = client.subscribe((channels.get(tfTopic) ?? fail(`no channel ${tfTopic}`)).id);
  client.subscribe(channel.id);
  await first;
  if (tfTopic && tfCount < 10) fail(`only ${tfCount} messages on ${tfTopic}`);
  phase = "paused";
  print({ kind: "playback", request: "pause", ...(await playback(1, 1, null, "pause")) });
  print({ kind: "playback", request: "seek", ...(await playback(1, 1, seekNs, "seek")) });
  phase = "after";
  const after = twenty("after the seek");
  print({ kind: "playback", request: "play", ...(await playback(0, 1, null, "play")) });
  await after;
  print({ kind: "done" });
  client.close();
  process.exit(0);
} catch (e) {
  fail(e?.message ?? e);
}
