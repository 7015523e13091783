// A rosbridge client (roslibjs, the npm package "roslib") for the tests: it subscribes to the
// topics named on the command line, steps the paused run through /cosim/step (roslibjs sends
// no service type: the server looks it up), publishes /cmd_vel, resumes through /cosim/pause,
// and prints one JSON summary line when the connection closes (or after --seconds).
//
//   node rosbridge_client.mjs ws://127.0.0.1:9090 --topics /odom,/scan --cmd-vel 0.5
import { Ros, Topic, Service } from "roslib";

const url = process.argv[2];
const arg = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const topics = arg("--topics", "/odom").split(",");
const speed = Number(arg("--cmd-vel", "0.5"));
const seconds = Number(arg("--seconds", "60"));
const cbor = new Set(arg("--cbor", "").split(",").filter(Boolean));

const summary = { topics: {}, step: null, resume: null, errors: [], published: 0 };
let done = false;
function finish() {
  if (done) return;
  done = true;
  process.stdout.write(JSON.stringify(summary) + "\n");
  process.exit(0);
}

async function connect() {
  for (let i = 0; i < 150; i++) {
    const ros = new Ros({});
    const opened = new Promise((resolve) => {
      ros.on("connection", () => resolve(true));
      ros.on("error", () => resolve(false));
      ros.on("close", () => resolve(false));
    });
    await ros.connect(url).catch(() => {});
    if (await opened) return ros;
    await new Promise((r) => setTimeout(r, 200));
  }
  throw new Error(`no rosbridge at ${url}`);
}

const ros = await connect();
ros.on("close", finish);
for (const name of topics) {
  const topic = new Topic({ ros, name, compression: cbor.has(name) ? "cbor" : "none" });
  topic.subscribe((msg) => {
    const entry = (summary.topics[name] ??= { count: 0, first: null, last: null });
    entry.count += 1;
    const brief = {};
    if (msg.header) brief.stamp = msg.header.stamp.sec * 1e9 + msg.header.stamp.nanosec;
    if (msg.pose?.pose?.position) brief.x = msg.pose.pose.position.x;
    if (msg.ranges) brief.ranges = msg.ranges.length;
    entry.first ??= brief;
    entry.last = brief;
  });
}
const call = (name, request) => new Promise((resolve) => {
  new Service({ ros, name }).callService(request, resolve,
                                         (err) => { summary.errors.push(String(err)); resolve(null); });
});
const cmdVel = new Topic({ ros, name: "/cmd_vel", messageType: "geometry_msgs/msg/Twist" });
await new Promise((r) => setTimeout(r, 300));
summary.step = await call("/cosim/step", {});
await new Promise((r) => setTimeout(r, 300));
const publish = () => {
  cmdVel.publish({ linear: { x: speed, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } });
  summary.published += 1;
};
publish();
summary.resume = await call("/cosim/pause", { data: false });
setInterval(publish, 100);
setTimeout(finish, seconds * 1000);
