// Independent readers of a flight.mcap written by hq-ground --record (run by flight_mcap.sh):
// @mcap/core reads the file (McapIndexedReader through the summary and chunk indexes, or
// McapStreamReader when the file has no summary: a SIGKILLed recorder), @foxglove/omgidl-parser
// parses the IDL each cdr channel carries as its schema and @foxglove/omgidl-serialization
// decodes every message with it; every JSON channel is parsed and its Foxglove payload checked.
//   node check_flight.cjs MODULES FILE.mcap SUMMARY.txt   (hq-ground's stdout: counts, stamps)
//   node check_flight.cjs MODULES FILE.mcap --killed KILL_NS
//       no summary expected; the last message is at most 1.5 s older than the SIGKILL at
//       KILL_NS (the host's real-time clock, as dds_time() and the log times)
//   node check_flight.cjs MODULES FILE.mcap --recovered KILL_NS
//       the killed file as hq-report --recover rewrote it: read through its summary and
//       indexes, the same 1.5 s bound
'use strict';
const fs = require('fs');
const path = require('path');

const [modules, mcapPath, expected, killNs] = process.argv.slice(2);
const need = (name) => require(path.resolve(modules, name));
const { McapIndexedReader, McapStreamReader } = need('@mcap/core');
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

async function readAll(bytes, handlers, killed) {
  const channels = new Map();
  const schemas = new Map();
  const messages = [];
  const metadata = new Map();
  let attachments = 0;
  if (!killed) {
    const readable = {
      size: async () => BigInt(bytes.length),
      read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
    };
    const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: handlers });
    for (const [id, c] of reader.channelsById) channels.set(id, c);
    for (const [id, s] of reader.schemasById) schemas.set(id, s);
    for await (const m of reader.readMessages({ validateCrcs: true })) messages.push(m);
    for await (const m of reader.readMetadata()) metadata.set(m.name, m.metadata);
    for await (const a of reader.readAttachments({ validateCrcs: true })) attachments++;
    check(reader.statistics && reader.statistics.messageCount === BigInt(messages.length),
          `statistics say ${reader.statistics?.messageCount}, read ${messages.length}`);
  } else {
    // What a viewer does with a file that has no footer: stream the records in order.
    const reader = new McapStreamReader({ decompressHandlers: handlers, validateCrcs: true });
    reader.append(bytes);
    try {
      for (let r; (r = reader.nextRecord());) {
        if (r.type === 'Schema') schemas.set(r.id, r);
        if (r.type === 'Channel') channels.set(r.id, r);
        if (r.type === 'Message') messages.push(r);
        if (r.type === 'Attachment') attachments++;
      }
    } catch (e) {
      check(false, `stream reader threw: ${e}`);
    }
    check(!reader.done(), 'a killed recording should have no footer');
  }
  return { channels, schemas, messages, metadata, attachments };
}

(async () => {
  const bytes = new Uint8Array(fs.readFileSync(mcapPath));
  const killed = expected === '--killed';
  const recovered = expected === '--recovered';
  const handlers = await loadDecompressHandlers();
  const { channels, schemas, messages, metadata, attachments } =
      await readAll(bytes, handlers, killed);

  const decoders = new Map();
  const byTopic = new Map();
  for (const [id, c] of channels) {
    byTopic.set(c.topic, { count: 0, first: 0n, last: 0n, id });
    const schema = schemas.get(c.schemaId);
    check(schema !== undefined, `${c.topic}: no schema`);
    if (c.messageEncoding === 'cdr') {
      check(schema.encoding === 'omgidl', `${c.topic}: schema encoding ${schema.encoding}`);
      const idl = new TextDecoder().decode(schema.data);
      decoders.set(id, new MessageReader(schema.name, parseIDL(idl)));
    } else {
      check(c.messageEncoding === 'json' && schema.encoding === 'jsonschema',
            `${c.topic}: encodings ${c.messageEncoding}/${schema.encoding}`);
      JSON.parse(new TextDecoder().decode(schema.data));
    }
  }

  const lastSequence = new Map();
  const decoded = {};
  for (const m of messages) {
    const c = channels.get(m.channelId);
    const t = byTopic.get(c.topic);
    if (t.count === 0) t.first = m.logTime;
    t.last = m.logTime;
    t.count++;
    check(m.publishTime > 0n && m.logTime > 0n, `${c.topic}: stamps ${m.publishTime} ${m.logTime}`);
    decoded[c.topic] = (decoded[c.topic] || 0) + 1;
    if (decoders.has(m.channelId)) {
      const msg = decoders.get(m.channelId).readMessage(m.data);
      if (c.topic === '/hq/heartbeat') continue;  // both sides' heartbeats: keyed by sender
      check(msg.vehicle_id === 1, `${c.topic}: vehicle_id ${msg.vehicle_id}`);
      const sequence = BigInt(msg.sequence_number);
      const previous = lastSequence.get(c.topic);
      check(previous === undefined || sequence > previous,
            `${c.topic}: sequence ${sequence} after ${previous}`);
      lastSequence.set(c.topic, sequence);
      if (c.topic === '/hq/velocity_command') {
        check(msg.station_id === 1 && Number.isFinite(msg.v_H_mps.z), 'command: bad values');
      }
      if (c.topic === '/hq/camera_frame') {
        check(msg.rgb_jpeg.length > 0 && msg.rgb_jpeg[0] === 0xff && msg.rgb_jpeg[1] === 0xd8,
              'camera frame: rgb_jpeg is not a JPEG');
      }
      if (c.topic === '/hq/vehicle_state') {
        check(Number.isFinite(msg.v_H_mps.x) && msg.obstacle_points_B_m.length <= 2048,
              'vehicle state: bad values');
      }
    } else {
      const msg = JSON.parse(new TextDecoder().decode(m.data));
      check(msg.timestamp && Number.isInteger(msg.timestamp.sec), `${c.topic}: no timestamp`);
      if (c.topic.startsWith('/camera/')) {
        const data = Buffer.from(msg.data, 'base64');
        const ok = msg.format === 'jpeg' ? data[0] === 0xff && data[1] === 0xd8
                                         : msg.format === 'png' && data[1] === 0x50;
        check(ok, `${c.topic}: ${msg.format} payload starts ${data[0]} ${data[1]}`);
      }
      if (c.topic === '/obstacles') {
        const data = Buffer.from(msg.data, 'base64');
        check(msg.point_stride === 12 && msg.fields.length === 3 && data.length % 12 === 0,
              `/obstacles: stride ${msg.point_stride}, ${data.length} bytes`);
      }
    }
  }

  const count = (topic) => byTopic.get(topic)?.count ?? 0;
  for (const topic of ['/hq/vehicle_state', '/hq/camera_frame', '/hq/heartbeat',
                       '/hq/velocity_command', '/ground/haptics', '/ground/link']) {
    check(count(topic) > 0, `${topic}: no messages`);
  }
  check(count('/camera/image/compressed') === count('/hq/camera_frame'), 'images != frames');
  check(count('/obstacles') === count('/hq/vehicle_state'), 'clouds != states');

  if (killed || recovered) {
    let last = 0n;
    for (const m of messages) if (m.logTime > last) last = m.logTime;
    const lost_s = Number(BigInt(killNs) - last) / 1e9;
    console.log(`${path.basename(mcapPath)}: last message ${lost_s.toFixed(3)} s before SIGKILL`);
    check(lost_s < 1.5, `the last ${lost_s.toFixed(3)} s before SIGKILL are lost (at most ~1 s expected)`);
  } else {
    // Against what hq-ground reported at exit.
    const text = fs.readFileSync(expected, 'utf8');
    const total = /mcap\s+(\d+) messages, (\d+) channels, (\d+) bytes, (\d+) attachments/.exec(text);
    check(total !== null, 'no "mcap: N messages" line in the summary');
    if (total) {
      check(BigInt(total[1]) === BigInt(messages.length), `${messages.length} messages, reported ${total[1]}`);
      check(Number(total[2]) === channels.size, `${channels.size} channels, reported ${total[2]}`);
      check(Number(total[3]) === bytes.length, `${bytes.length} bytes, reported ${total[3]}`);
      check(Number(total[4]) === attachments, `${attachments} attachments, reported ${total[4]}`);
    }
    let lines = 0;
    for (const [, topic, n, first, last] of text.matchAll(/mcap channel (\S+) (\d+) (\d+) (\d+)/g)) {
      lines++;
      const t = byTopic.get(topic) || { count: 0, first: 0n, last: 0n };
      check(t.count === Number(n) && t.first === BigInt(first) && t.last === BigInt(last),
            `${topic}: read ${t.count} ${t.first}..${t.last}, reported ${n} ${first}..${last}`);
    }
    check(lines === channels.size, `${lines} channel lines for ${channels.size} channels`);
    check(metadata.has('flight_summary') && metadata.has('recorder'), 'metadata missing');
    const summary = metadata.get('flight_summary');
    check(summary && Number(summary.get('commands_sent')) > 0, 'flight_summary: commands_sent');
  }
  console.log(`${path.basename(mcapPath)}: ${messages.length} messages on ${channels.size} ` +
              `channels, ${decoders.size} cdr channels decoded with their omgidl schema, ` +
              `${attachments} attachments${killed ? ' (killed: streamed without summary)' : ''}` +
              `${recovered ? ' (recovered: read through its new summary)' : ''}: ` +
              JSON.stringify(decoded));
  if (failures > 0) {
    console.error(`${failures} failure(s)`);
    process.exit(1);
  }
})().catch((e) => {
  console.error(`${mcapPath}: ${e.stack || e}`);
  process.exit(1);
});
