// A Foxglove WebSocket client (Foxglove's own @foxglove/ws-protocol) for the tests: it
// subscribes to the topics named on the command line, decodes every message with the ROS 2
// CDR reader built from the schema the server advertised, steps the paused run once through
// the /cosim/step service, resumes it through /cosim/pause, and prints one JSON summary line
// when the server goes away (or after --seconds).
//
//   node foxglove_client.mjs ws://127.0.0.1:8765 --topics /odom,/camera/color/image_raw
//   (--drive no: no service calls; --stall: stop reading once subscribed, a stuck client)
import wsProtocol from "@foxglove/ws-protocol";
import rosmsg from "@foxglove/rosmsg";
import serialization from "@foxglove/rosmsg2-serialization";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;
const { parse } = rosmsg;
const { MessageReader, MessageWriter } = serialization;
const url = process.argv[2];
const arg = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const wanted = new Set(arg("--topics", "/odom").split(","));
const seconds = Number(arg("--seconds", "60"));
const drive = arg("--drive", "yes") === "yes";
const stall = process.argv.includes("--stall"); // stop reading once subscribed (a stuck client)

const summary = { topics: {}, times: 0, first_time: null, last_time: null, services: [],
                  step: null, resume: null, schemas: {}, errors: [] };
const readers = new Map(); // subscription id -> [topic, reader]
const services = new Map();
const pending = new Map(); // call id -> [name, response reader]
let callId = 0;

function connect(triesLeft) {
  // foxglove-sdk servers speak this protocol under the name "foxglove.sdk.v1" (as the
  // Foxglove app and foxglove_bridge do); the client takes whichever subprotocol it is given.
  const ws = new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  ws.on("error", () => {});
  const client = new FoxgloveClient({ ws });
  let abandoned = false; // retried on a new connection: this one is closed and ignored
  client.on("error", (e) => {
    if (abandoned) return;
    if (triesLeft > 0 && summary.times === 0 && readers.size === 0) {
      // an error need not close the socket: close it, or the server counts (and feeds) this
      // client beside its retry (a CI run once saw 3 clients at once where 2 connected)
      abandoned = true;
      try { client.close(); } catch { /* already closed */ }
      setTimeout(() => connect(triesLeft - 1), 200);
    } else {
      summary.errors.push(String(e));
    }
  });
  client.on("advertise", (channels) => {
    if (abandoned) return;
    for (const channel of channels) {
      if (!wanted.has(channel.topic)) continue;
      summary.schemas[channel.topic] = [channel.encoding, channel.schemaEncoding, channel.schemaName];
      const reader = new MessageReader(parse(channel.schema, { ros2: true }));
      readers.set(client.subscribe(channel.id), [channel.topic, reader]);
    }
    if (stall) setTimeout(() => ws._socket.pause(), 200);
  });
  client.on("message", ({ subscriptionId, timestamp, data }) => {
    if (abandoned) return;
    const [topic, reader] = readers.get(subscriptionId);
    const msg = reader.readMessage(data);
    const entry = (summary.topics[topic] ??= { count: 0, first: null, last: null });
    entry.count += 1;
    const brief = describe(topic, msg, timestamp);
    entry.first ??= brief;
    entry.last = brief;
  });
  client.on("time", ({ timestamp }) => {
    if (abandoned) return;
    summary.times += 1;
    summary.first_time ??= Number(timestamp);
    summary.last_time = Number(timestamp);
  });
  client.on("advertiseServices", (list) => {
    if (abandoned) return;
    for (const service of list) {
      services.set(service.name, service);
      summary.services.push([service.name, service.type]);
    }
    if (drive && services.has("/cosim/step") && services.has("/cosim/pause")) {
      call("/cosim/step", {}, "step");
    }
  });
  client.on("serviceCallResponse", ({ callId: id, data }) => {
    if (abandoned) return;
    const [what, reader] = pending.get(id);
    summary[what] = reader.readMessage(data);
    if (what === "step") setTimeout(() => call("/cosim/pause", { data: false }, "resume"), 300);
  });
  client.on("serviceCallFailure", (failure) => summary.errors.push(failure.message));
  client.on("close", () => {
    if (abandoned) return;
    if (readers.size > 0 || summary.times > 0) finish();
  });

  function call(name, request, what) {
    const service = services.get(name);
    const writer = new MessageWriter(parse(service.request.schema, { ros2: true }));
    const reader = new MessageReader(parse(service.response.schema, { ros2: true }));
    callId += 1;
    pending.set(callId, [what, reader]);
    client.sendServiceCallRequest({ serviceId: service.id, callId, encoding: "cdr",
                                    data: writer.writeMessage(request) });
  }
}

function describe(topic, msg, timestamp) {
  const out = { log_time: Number(timestamp) };
  if (msg.header) out.frame_id = msg.header.frame_id;
  if (msg.header) out.stamp = msg.header.stamp.sec * 1e9 + msg.header.stamp.nanosec;
  if (msg.pose?.pose?.position) out.x = msg.pose.pose.position.x;
  if (msg.transforms) out.transforms = msg.transforms.map((t) => t.child_frame_id);
  if (msg.encoding !== undefined && msg.data !== undefined) {
    Object.assign(out, { width: msg.width, height: msg.height, encoding: msg.encoding,
                         bytes: msg.data.length });
  }
  if (msg.ranges) out.ranges = msg.ranges.length;
  return out;
}

let done = false;
function finish() {
  if (done) return;
  done = true;
  const cpu = process.cpuUsage();
  summary.cpu_s = (cpu.user + cpu.system) / 1e6;
  process.stdout.write(JSON.stringify(summary) + "\n");
  process.exit(0);
}

setTimeout(finish, seconds * 1000);
connect(150);
