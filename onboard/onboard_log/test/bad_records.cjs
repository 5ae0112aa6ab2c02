// Writes small MCAP files with @mcap/core's writer for the MCAP check's negative test: one good
// file and one per fault (backwards log time, two clocks, an image frame without a transform,
// a ros2-profile channel whose schema does not parse, a ros2 message cut short), and a good ros2
// file. Usage: node bad_records.cjs NODE_MODULES DIR
'use strict';
const fs = require('fs');
const { McapWriter } = require(`${process.argv[2]}/@mcap/core`);
const dir = process.argv[3];

class FileWritable {
  constructor() { this.chunks = []; this.size = 0n; }
  position() { return this.size; }
  async write(buffer) { this.chunks.push(Buffer.from(buffer)); this.size += BigInt(buffer.byteLength); }
}

const json = (o) => new TextEncoder().encode(JSON.stringify(o));
const stamp = (ns) => ({ sec: Number(ns / 1000000000n), nsec: Number(ns % 1000000000n) });
const epoch = 1796000000000000000n;

// rosgraph_msgs/msg/Clock's definition as rosbag2 stores it: valid, so only a message can fail.
const clockMsg = 'builtin_interfaces/Time clock\n' + '='.repeat(80) +
  '\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n';

async function write(name, { profile = '', messages, rosSchema }) {
  const out = new FileWritable();
  const w = new McapWriter({ writable: out });
  await w.start({ profile, library: 'bad_records.cjs' });
  const channels = {};
  if (profile === 'ros2') {
    const bad = await w.registerSchema(rosSchema || { name: 'std_msgs/msg/Bad', encoding: 'ros2msg', data: new TextEncoder().encode('int32 x\nno_such_type/Foo y\n') });
    channels.ros = await w.registerChannel({ topic: '/bad', schemaId: bad, messageEncoding: 'cdr', metadata: new Map() });
  } else {
    const tfSchema = await w.registerSchema({ name: 'foxglove.FrameTransform', encoding: 'jsonschema', data: json({}) });
    const imgSchema = await w.registerSchema({ name: 'foxglove.CompressedImage', encoding: 'jsonschema', data: json({}) });
    channels.tf = await w.registerChannel({ topic: '/tf', schemaId: tfSchema, messageEncoding: 'json', metadata: new Map() });
    channels.img = await w.registerChannel({ topic: '/camera/image/compressed', schemaId: imgSchema, messageEncoding: 'json', metadata: new Map() });
  }
  let sequence = 0;
  for (const [channel, logTime, payload] of messages) {
    await w.addMessage({ channelId: channels[channel], sequence: sequence++, logTime, publishTime: logTime, data: payload });
  }
  await w.end();
  fs.writeFileSync(`${dir}/${name}.mcap`, Buffer.concat(out.chunks));
}

const transform = (t, parent, child) => json({ timestamp: stamp(t), parent_frame_id: parent, child_frame_id: child,
  translation: { x: 0, y: 0, z: 0 }, rotation: { x: 0, y: 0, z: 0, w: 1 } });
const image = (t, frame) => json({ timestamp: stamp(t), frame_id: frame, data: '/9j/', format: 'jpeg' });

(async () => {
  const ms = 1000000n;
  const good = [
    ['tf', epoch, transform(epoch, 'odom', 'base_link')],
    ['tf', epoch, transform(epoch, 'base_link', 'camera_optical')],
    ['img', epoch + 10n * ms, image(epoch + 10n * ms, 'camera_optical')],
    ['img', epoch + 20n * ms, image(epoch + 20n * ms, 'camera_optical')],
  ];
  await write('good', { messages: good });
  await write('backwards', { messages: [good[0], good[1], good[3], good[2]] });
  // In log-time order, but the images on a clock that started at 0.
  await write('two_clocks', { messages: [['img', 5n * ms, image(5n * ms, 'camera_optical')], good[0], good[1]] });
  await write('no_transform', { messages: [good[0], ['img', epoch + 10n * ms, image(epoch + 10n * ms, 'camera')]] });
  await write('ros2_bad_schema', { profile: 'ros2', messages: [['ros', epoch, new Uint8Array([0, 1, 0, 0, 1, 0, 0, 0])]] });
  // A Clock cut after its seconds: the schema parses, the message does not decode.
  const clock = { name: 'rosgraph_msgs/msg/Clock', encoding: 'ros2msg', data: new TextEncoder().encode(clockMsg) };
  await write('ros2_good', { profile: 'ros2', rosSchema: clock,
    messages: [['ros', epoch, new Uint8Array([0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0])]] });
  await write('ros2_bad_message', { profile: 'ros2', rosSchema: clock,
    messages: [['ros', epoch, new Uint8Array([0, 1, 0, 0, 1, 0, 0, 0])]] });
})().catch((e) => { console.error(e.stack || e); process.exit(1); });
