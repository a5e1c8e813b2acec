// Foxglove's playback control over a client of the npm package @foxglove/ws-protocol, which
// has none: its requests go as raw frames on the client's socket, and the server's Playback
// State frames (opcode 5), which the package does not know and reports as errors, are read
// from the socket here. Shared by client.mjs and replay.mjs.

/// Rejects after `ms` with a message naming `what`.
export const within = (ms, what, promise) =>
  Promise.race([
    promise,
    new Promise((_, reject) => setTimeout(() => reject(new Error(`no ${what} within ${ms} ms`)), ms)),
  ]);

/// Whether an error the package reports is only a Playback State frame it does not know.
export const isPlaybackState = (error) =>
  String(error?.message ?? error).includes("Unrecognized server opcode in binary message: 5");

/// Playback control on socket `ws`: `request(command, speed, seekNs, id)` sends a Playback
/// Control Request (command 0 play, 1 pause; seekNs null for none) and resolves with the
/// Playback State that answers it: { status, currentTime, speed, didSeek, requestId }.
export function playbackControl(ws) {
  let waiter = null;
  ws.on("message", (data, isBinary) => {
    // The client asks for ArrayBuffers.
    const b = Buffer.from(data);
    if (!isBinary || b[0] !== 5) return;
    // op, status, current time (u64), speed (f32), did seek, request id (u32 length, UTF-8).
    const idLen = b.readUInt32LE(15);
    waiter?.({
      status: b[1], currentTime: b.readBigUInt64LE(2).toString(), speed: b.readFloatLE(10), didSeek: b[14] === 1,
      requestId: b.subarray(19, 19 + idLen).toString("utf8"),
    });
  });
  return (command, speed, seekNs, requestId) => {
    const id = Buffer.from(requestId, "utf8");
    const b = Buffer.alloc(19 + id.length);
    b[0] = 3;
    b[1] = command;
    b.writeFloatLE(speed, 2);
    b[6] = seekNs === null ? 0 : 1;
    b.writeBigUInt64LE(BigInt(seekNs ?? 0), 7);
    b.writeUInt32LE(id.length, 15);
    id.copy(b, 19);
    const answered = new Promise((resolve) => {
      waiter = (s) => { if (s.requestId === requestId) resolve(s); };
    });
    ws.send(b);
    return within(30000, `the playback state answering ${requestId}`, answered);
  };
}
