// The MCAP flight-record check behind scripts/check-mcap: reads each file with npm's readers
// (@mcap/core, @mcap/support for zstd) and fails on what a ROS 2 or Foxglove user would meet:
//   clock      channels whose first log times lie more than --max-clock-span-s apart (two
//              clocks in one file: Foxglove shows one decades-long timeline)
//   order      a log time lower than the one before it in file order (`mcap doctor`'s warning)
//   frames     a frame named by an image, calibration or point cloud with no transform path
//              (foxglove.FrameTransform, or tf2_msgs/msg/TFMessage) to --root-frame
//   foxglove   a json message of a foxglove.* schema with a field the official schema
//              (@foxglove/schemas) lacks, of another type, or missing one of its fields
//   ros2       in a file of the ros2 profile, a cdr channel whose ros2msg schema does not parse
//              (@foxglove/rosmsg) or a message it does not decode (@foxglove/rosmsg2-serialization)
// Usage: node check-mcap.cjs NODE_MODULES [--max-clock-span-s S] [--root-frame F] FILE...
'use strict';
const fs = require('fs');

const modules = process.argv[2];
const { McapStreamReader } = require(`${modules}/@mcap/core`);
const { loadDecompressHandlers } = require(`${modules}/@mcap/support`);
const foxglove = require(`${modules}/@foxglove/schemas/jsonschema`);
const { parse: parseRosMsg } = require(`${modules}/@foxglove/rosmsg`);
const { MessageReader } = require(`${modules}/@foxglove/rosmsg2-serialization`);

const args = process.argv.slice(3);
let maxClockSpanS = 60;
let rootFrame = 'odom';
const files = [];
for (let i = 0; i < args.length; ++i) {
  if (args[i] === '--max-clock-span-s') maxClockSpanS = Number(args[++i]);
  else if (args[i] === '--root-frame') rootFrame = args[++i];
  else files.push(args[i]);
}
if (files.length === 0 || !(maxClockSpanS > 0)) {
  console.error('usage: check-mcap [--max-clock-span-s S] [--root-frame F] FILE.mcap...');
  process.exit(2);
}

// The official schema's JSON types, checked both ways (nothing extra, nothing missing).
function checkAgainst(schema, value, where, problems) {
  if (problems.length > 5) return;
  const types = [].concat(schema.type || []);
  const actual = Array.isArray(value) ? 'array' : value === null ? 'null' : typeof value;
  const ok = types.length === 0 || types.some((t) =>
    t === actual || (t === 'integer' && Number.isInteger(value)) ||
    (t === 'number' && actual === 'number'));
  if (!ok) {
    problems.push(`${where}: ${actual}, the official schema says ${types.join('|')}`);
    return;
  }
  if (actual === 'object' && schema.properties) {
    for (const key of Object.keys(value)) {
      if (!(key in schema.properties)) problems.push(`${where}.${key}: not in the official schema`);
      else checkAgainst(schema.properties[key], value[key], `${where}.${key}`, problems);
    }
    for (const key of Object.keys(schema.properties)) {
      if (!(key in value)) problems.push(`${where}.${key}: missing`);
    }
  } else if (actual === 'array' && schema.items) {
    value.forEach((v, i) => checkAgainst(schema.items, v, `${where}[${i}]`, problems));
  }
}

function frameGraph() {
  const parents = new Map();  // child -> parent
  return {
    add(parent, child) { if (parent && child) parents.set(child, parent); },
    reaches(frame) {
      const seen = new Set();
      for (let f = frame; f !== undefined && !seen.has(f); f = parents.get(f)) {
        if (f === rootFrame) return true;
        seen.add(f);
      }
      return false;
    },
  };
}

async function checkFile(path, handlers) {
  const failures = [];
  const fail = (what) => failures.push(what);
  const reader = new McapStreamReader({ decompressHandlers: handlers });
  reader.append(fs.readFileSync(path));
  const schemas = new Map();
  const channels = new Map();
  const firstLog = new Map();
  const frames = frameGraph();
  const framesUsed = new Map();  // frame -> topic
  const foxgloveProblems = new Map();
  const rosReaders = new Map();
  const rosFailures = new Map();
  let profile = '';
  let messages = 0;
  let backwards = 0;
  let worstBackNs = 0n;
  let previous;
  let record;
  while ((record = reader.nextRecord())) {
    if (record.type === 'Header') profile = record.profile;
    if (record.type === 'Schema') schemas.set(record.id, record);
    if (record.type === 'Channel') channels.set(record.id, record);
    if (record.type !== 'Message') continue;
    ++messages;
    if (previous !== undefined && record.logTime < previous) {
      ++backwards;
      if (previous - record.logTime > worstBackNs) worstBackNs = previous - record.logTime;
    }
    previous = record.logTime;
    const channel = channels.get(record.channelId);
    const schema = schemas.get(channel.schemaId);
    if (!firstLog.has(channel.topic)) firstLog.set(channel.topic, record.logTime);
    if (channel.messageEncoding === 'json' && schema && schema.name.startsWith('foxglove.')) {
      const msg = JSON.parse(Buffer.from(record.data).toString('utf8'));
      const official = foxglove[schema.name.slice('foxglove.'.length)];
      const problems = foxgloveProblems.get(channel.topic) || [];
      if (!official) problems.push(`${schema.name}: no such official schema`);
      else checkAgainst(official, msg, schema.name, problems);
      foxgloveProblems.set(channel.topic, problems);
      if (schema.name === 'foxglove.FrameTransform') frames.add(msg.parent_frame_id, msg.child_frame_id);
      else if (msg.frame_id !== undefined) framesUsed.set(msg.frame_id, channel.topic);
    }
    if (channel.messageEncoding === 'cdr' && schema && schema.encoding === 'ros2msg') {
      if (!rosReaders.has(channel.id)) {
        try {
          const text = Buffer.from(schema.data).toString('utf8');
          rosReaders.set(channel.id, new MessageReader(parseRosMsg(text, { ros2: true })));
        } catch (e) {
          rosReaders.set(channel.id, null);
          rosFailures.set(channel.topic, `schema ${schema.name} does not parse: ${e.message}`);
        }
      }
      const decoder = rosReaders.get(channel.id);
      if (decoder) {
        try {
          const msg = decoder.readMessage(record.data);
          if (schema.name === 'tf2_msgs/msg/TFMessage') {
            for (const t of msg.transforms) frames.add(t.header.frame_id, t.child_frame_id);
          } else if (msg.header && msg.header.frame_id) {
            framesUsed.set(msg.header.frame_id, channel.topic);
          }
        } catch (e) {
          if (!rosFailures.has(channel.topic)) {
            rosFailures.set(channel.topic, `a message does not decode with ${schema.name}: ${e.message}`);
          }
        }
      }
    }
  }
  if (messages === 0) fail('no messages');
  if (backwards > 0) {
    fail(`order: ${backwards} of ${messages} messages go back in log time ` +
         `(worst ${(Number(worstBackNs) / 1e6).toFixed(3)} ms)`);
  }
  const firsts = [...firstLog.entries()].sort((a, b) => (a[1] < b[1] ? -1 : 1));
  if (firsts.length > 1) {
    const spanS = Number(firsts[firsts.length - 1][1] - firsts[0][1]) / 1e9;
    if (spanS > maxClockSpanS) {
      fail(`clock: channels start ${spanS.toFixed(3)} s apart (more than ${maxClockSpanS} s: ` +
           `two clocks?): ${firsts[0][0]} at ${firsts[0][1]} ns, ` +
           `${firsts[firsts.length - 1][0]} at ${firsts[firsts.length - 1][1]} ns`);
    }
  }
  for (const [frame, topic] of framesUsed) {
    if (!frames.reaches(frame)) fail(`frames: ${topic} names frame "${frame}" with no transform path to ${rootFrame}`);
  }
  for (const [topic, problems] of foxgloveProblems) {
    if (problems.length > 0) fail(`foxglove: ${topic}: ${problems.slice(0, 5).join('; ')}`);
  }
  if (profile === 'ros2') {
    for (const c of channels.values()) {
      const s = schemas.get(c.schemaId);
      if (c.messageEncoding !== 'cdr' || !s || s.encoding !== 'ros2msg') {
        fail(`ros2: ${c.topic} is ${c.messageEncoding}/${s ? s.encoding : 'no schema'}, the ros2 profile wants cdr/ros2msg`);
      }
    }
  }
  for (const [topic, what] of rosFailures) fail(`ros2: ${topic}: ${what}`);
  const summary = `${path}: ${messages} messages on ${channels.size} channels, profile ` +
                  `"${profile}", ${framesUsed.size} frame(s) used, ${rosReaders.size} ros2 channel(s) decoded`;
  return { summary, failures };
}

(async () => {
  const handlers = await loadDecompressHandlers();
  let failed = 0;
  for (const path of files) {
    let result;
    try {
      result = await checkFile(path, handlers);
    } catch (e) {
      result = { summary: path, failures: [`unreadable: ${e.message}`] };
    }
    console.log(result.summary);
    for (const f of result.failures) console.log(`  FAIL ${f}`);
    if (result.failures.length > 0) ++failed;
  }
  console.log(failed === 0 ? 'check-mcap: OK' : `check-mcap: ${failed} file(s) failed`);
  process.exit(failed === 0 ? 0 : 1);
})();
