// Independent readers of an onboard.mcap written by hq-onboard --record (run by
// onboard_mcap.sh): @mcap/core reads the file through its summary and chunk indexes with CRCs
// checked, @foxglove/omgidl-parser parses the IDL each cdr channel carries and
// @foxglove/omgidl-serialization decodes every link message with it; every JSON message is
// parsed. Counts are checked against hq-onboard's exit summary ("record TOPIC N messages").
//   node check_onboard.cjs MODULES FILE.mcap SUMMARY.txt
'use strict';
const fs = require('fs');
const path = require('path');

const [modules, mcapPath, summaryPath] = process.argv.slice(2);
const need = (name) => require(path.resolve(modules, name));
const { McapIndexedReader } = need('@mcap/core');
const { loadDecompressHandlers } = need('@mcap/support');
const { parseIDL } = need('@foxglove/omgidl-parser');
const { MessageReader } = need('@foxglove/omgidl-serialization');

let failures = 0;
function check(condition, message) {
  if (!condition) {
    console.error(`${path.basename(mcapPath)}: ${message}`);
    failures++;
  }
}

(async () => {
  const bytes = new Uint8Array(fs.readFileSync(mcapPath));
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({
    readable, decompressHandlers: await loadDecompressHandlers() });
  const decoders = new Map();
  const counts = new Map();
  const lastLog = new Map();
  for (const [id, c] of reader.channelsById) {
    counts.set(c.topic, 0);
    const schema = reader.schemasById.get(c.schemaId);
    check(schema !== undefined, `${c.topic}: no schema`);
    if (c.messageEncoding === 'cdr') {
      check(schema.encoding === 'omgidl', `${c.topic}: schema encoding ${schema.encoding}`);
      decoders.set(id, new MessageReader(schema.name, parseIDL(new TextDecoder().decode(schema.data))));
    } else {
      check(c.messageEncoding === 'json' && schema.encoding === 'jsonschema',
            `${c.topic}: encodings ${c.messageEncoding}/${schema.encoding}`);
      JSON.parse(new TextDecoder().decode(schema.data));
    }
  }
  let total = 0;
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const c = reader.channelsById.get(m.channelId);
    total++;
    counts.set(c.topic, counts.get(c.topic) + 1);
    const previous = lastLog.get(c.topic);
    check(previous === undefined || m.logTime >= previous, `${c.topic}: log time went back`);
    lastLog.set(c.topic, m.logTime);
    if (decoders.has(m.channelId)) {
      const msg = decoders.get(m.channelId).readMessage(m.data);
      if (c.topic === '/hq/vehicle_state') {
        check(Number.isFinite(msg.v_H_mps.x), 'vehicle state: v_H_mps not finite');
      }
      if (c.topic === '/hq/velocity_command') {
        check(Number.isFinite(msg.v_H_mps.x), 'velocity command: v_H_mps not finite');
      }
    } else {
      const msg = JSON.parse(new TextDecoder().decode(m.data));
      check(msg.timestamp && Number.isInteger(msg.timestamp.sec), `${c.topic}: no timestamp`);
      if (c.topic === '/onboard/estimator') {
        check('v_H_mps' in msg && 'v_B_mps' in msg && 'roll_rad' in msg, 'estimator: fields');
      }
      if (c.topic === '/onboard/control') {
        check(typeof msg.mode === 'string' && 'thrust_n' in msg, 'control: fields');
      }
    }
  }
  check(reader.statistics && reader.statistics.messageCount === BigInt(total),
        `statistics say ${reader.statistics?.messageCount}, read ${total}`);
  const text = fs.readFileSync(summaryPath, 'utf8');
  let lines = 0;
  for (const [, topic, n] of text.matchAll(/^  record (\S+) +(\d+) messages$/gm)) {
    lines++;
    check(counts.get(topic) === Number(n), `${topic}: read ${counts.get(topic)}, reported ${n}`);
  }
  check(lines === reader.channelsById.size, `${lines} lines for ${reader.channelsById.size} channels`);
  for (const topic of ['/hq/vehicle_state', '/hq/camera_frame', '/hq/heartbeat',
                       '/hq/velocity_command', '/onboard/imu', '/onboard/odometry',
                       '/onboard/estimator', '/onboard/control', '/onboard/timing']) {
    check(counts.get(topic) > 0, `${topic}: no messages`);
  }
  let summary;
  for await (const m of reader.readMetadata({ name: 'flight_summary' })) summary = m.metadata;
  check(summary && Number(summary.get('frames')) > 0, 'flight_summary: frames');
  console.log(`${path.basename(mcapPath)}: ${total} messages on ${reader.channelsById.size} ` +
              `channels, ${decoders.size} cdr channels decoded with their omgidl schema: ` +
              JSON.stringify(Object.fromEntries(counts)));
  if (failures > 0) {
    console.error(`${failures} failure(s)`);
    process.exit(1);
  }
})().catch((e) => {
  console.error(`${mcapPath}: ${e.stack || e}`);
  process.exit(1);
});
