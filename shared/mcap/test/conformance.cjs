// The @mcap/core side of the conformance check (run by conformance.sh).
//   node conformance.cjs MODULES read FILE.mcap FILE.json
//       Files with a summary are read with McapIndexedReader (summary, chunk indexes, seeking by
//       topic and time window, CRCs validated) and with McapStreamReader; a file without its
//       summary (a killed writer) must be refused by the indexed reader and stream up to its
//       last chunk.
//   node conformance.cjs MODULES write FILE.mcap FILE.txt CHUNKS
//       @mcap/core's McapWriter writes a recording (zstd chunks from @foxglove/wasm-zstd when
//       CHUNKS is "zstd", no chunks when "none") and the values for hq-mcap-conformance check.
'use strict';
const fs = require('fs');
const path = require('path');

const [modules, mode, mcapPath, jsonPath, chunking] = process.argv.slice(2);
const { McapIndexedReader, McapStreamReader, McapWriter } = require(path.resolve(modules, '@mcap/core'));
const { loadDecompressHandlers } = require(path.resolve(modules, '@mcap/support'));

const bytes = mode === 'read' ? new Uint8Array(fs.readFileSync(mcapPath)) : undefined;
const want = mode === 'read' ? JSON.parse(fs.readFileSync(jsonPath, 'utf8')) : undefined;
const name = path.basename(mcapPath);
let failures = 0;
function fail(message) {
  console.error(`${name}: ${message}`);
  failures++;
}
function check(condition, message) {
  if (!condition) fail(message);
}

function byteSum(data) {
  let sum = 0;
  for (const b of data) sum = (sum + b) >>> 0;
  return sum;
}

// Compares messages (in log-time order) with the writer's list.
function checkMessages(got, expected, how) {
  check(got.length === expected.length,
        `${how}: ${got.length} messages, the writer wrote ${expected.length}`);
  const n = Math.min(got.length, expected.length);
  let shown = 0;
  for (let i = 0; i < n; i++) {
    const m = got[i];
    const [channel, sequence, logTime, publishTime, size, sum] = expected[i];
    const ok = m.channelId === channel && m.sequence === sequence &&
        m.logTime === BigInt(logTime) && m.publishTime === BigInt(publishTime) &&
        m.data.length === size && byteSum(m.data) === sum;
    if (!ok && shown++ < 5) {
      fail(`${how}: message ${i} is channel ${m.channelId} seq ${m.sequence} log ${m.logTime} ` +
           `publish ${m.publishTime} ${m.data.length} B sum ${byteSum(m.data)}, expected ` +
           JSON.stringify(expected[i]));
    }
  }
}

function checkChannels(channelsById, schemasById, how) {
  check(channelsById.size === want.channels.length,
        `${how}: ${channelsById.size} channels, expected ${want.channels.length}`);
  for (const c of want.channels) {
    const got = channelsById.get(c.id);
    if (!got) {
      fail(`${how}: channel ${c.id} missing`);
      continue;
    }
    check(got.topic === c.topic, `${how}: channel ${c.id} topic ${got.topic}, expected ${c.topic}`);
    const schema = got.schemaId === 0 ? '' : schemasById.get(got.schemaId)?.name;
    check(schema === c.schema, `${how}: channel ${c.id} schema ${schema}, expected ${c.schema}`);
  }
}

async function indexed(handlers) {
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  if (!want.summary) {
    let refused = false;
    try {
      await McapIndexedReader.Initialize({ readable, decompressHandlers: handlers });
    } catch (e) {
      refused = true;
    }
    check(refused, 'indexed reader accepted a file without footer');
    return;
  }
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: handlers });
  const s = reader.statistics;
  check(s !== undefined, 'no Statistics record');
  if (s) {
    const w = want.statistics;
    check(s.messageCount === BigInt(w.messages), `statistics: ${s.messageCount} messages, expected ${w.messages}`);
    check(s.schemaCount === w.schemas, `statistics: ${s.schemaCount} schemas`);
    check(s.channelCount === w.channels, `statistics: ${s.channelCount} channels`);
    check(s.attachmentCount === w.attachments, `statistics: ${s.attachmentCount} attachments`);
    check(s.metadataCount === w.metadata, `statistics: ${s.metadataCount} metadata`);
    check(s.chunkCount === w.chunks, `statistics: ${s.chunkCount} chunks, expected ${w.chunks}`);
    check(s.messageStartTime === BigInt(w.start) && s.messageEndTime === BigInt(w.end),
          `statistics: times ${s.messageStartTime}..${s.messageEndTime}, expected ${w.start}..${w.end}`);
    for (const c of want.channels) {
      const count = want.messages.filter((m) => m[0] === c.id).length;
      check(s.channelMessageCounts.get(c.id) === BigInt(count),
            `statistics: channel ${c.id} count ${s.channelMessageCounts.get(c.id)}, expected ${count}`);
    }
  }
  check(reader.chunkIndexes.length === want.statistics.chunks,
        `${reader.chunkIndexes.length} chunk indexes, expected ${want.statistics.chunks}`);
  checkChannels(reader.channelsById, reader.schemasById, 'indexed');

  const all = [];
  for await (const m of reader.readMessages({ validateCrcs: true })) all.push(m);
  checkMessages(all, want.messages, 'indexed, all');

  // Seeking: one topic in a time window in the middle, through the chunk and message indexes.
  const start = BigInt(want.messages[Math.floor(want.messages.length / 3)][2]);
  const end = BigInt(want.messages[Math.floor(want.messages.length / 2)][2]);
  const window = [];
  for await (const m of reader.readMessages({ topics: ['/camera/jpeg'], startTime: start, endTime: end })) {
    window.push(m);
  }
  checkMessages(window, want.messages.filter((m) => m[0] === 1 && BigInt(m[2]) >= start &&
                                                    BigInt(m[2]) <= end), 'indexed, window');
  const reversed = [];
  for await (const m of reader.readMessages({ reverse: true })) reversed.push(m);
  checkMessages(reversed.reverse(), want.messages, 'indexed, reverse');

  const attachments = [];
  for await (const a of reader.readAttachments({ validateCrcs: true })) attachments.push(a);
  check(JSON.stringify(attachments.map((a) => [a.name, a.mediaType, a.data.length])) ===
        JSON.stringify(want.attachments.map((a) => [a.name, a.media_type, a.size])),
        `indexed: attachments ${attachments.map((a) => a.name)}`);
  const metadata = [];
  for await (const m of reader.readMetadata()) metadata.push(m);
  check(metadata.length === want.metadata.length && metadata[0].name === want.metadata[0].name &&
        JSON.stringify(Object.fromEntries(metadata[0].metadata)) ===
            JSON.stringify(want.metadata[0].values),
        `indexed: metadata ${JSON.stringify(metadata.map((m) => [m.name, [...m.metadata]]))}`);
  console.log(`${name}: indexed reader: ${all.length} messages in ${reader.chunkIndexes.length} ` +
              `chunks, ${window.length} by seeking, ${attachments.length} attachments, ` +
              `${metadata.length} metadata`);
}

function streamed(handlers) {
  const reader = new McapStreamReader({ decompressHandlers: handlers, validateCrcs: true });
  const counts = {};
  const messages = [];
  const schemas = new Map();
  const channels = new Map();
  // Fed in 4 kB pieces, as a live stream arrives.
  for (let at = 0; at < bytes.length; at += 4096) {
    reader.append(bytes.subarray(at, Math.min(at + 4096, bytes.length)));
    for (let record; (record = reader.nextRecord());) {
      counts[record.type] = (counts[record.type] || 0) + 1;
      if (record.type === 'Message') messages.push(record);
      if (record.type === 'Schema') schemas.set(record.id, record);
      if (record.type === 'Channel') channels.set(record.id, record);
    }
  }
  messages.sort((a, b) => (a.logTime < b.logTime ? -1 : a.logTime > b.logTime ? 1 : 0));
  checkMessages(messages, want.messages, 'stream');
  checkChannels(channels, schemas, 'stream');
  check(reader.done() === want.summary, `stream: done() is ${reader.done()}`);
  if (want.summary) {
    for (const type of ['Header', 'DataEnd', 'Statistics', 'Footer']) {
      check(counts[type] === 1, `stream: ${counts[type] || 0} ${type} records`);
    }
    check(counts.Chunk === undefined, 'stream: chunks not expanded');
    check(counts.ChunkIndex === want.statistics.chunks, `stream: ${counts.ChunkIndex} ChunkIndex`);
  }
  check(counts.Attachment === want.attachments.length, `stream: ${counts.Attachment} attachments`);
  check(counts.Metadata === want.metadata.length, `stream: ${counts.Metadata} metadata`);
  console.log(`${name}: stream reader: ${JSON.stringify(counts)}`);
}

async function write() {
  const zstd = require(path.resolve(modules, '@foxglove/wasm-zstd'));
  await zstd.isLoaded;
  const parts = [];
  let size = 0n;
  const writable = {
    position: () => size,
    write: async (buffer) => {
      parts.push(Buffer.from(buffer));
      size += BigInt(buffer.length);
    },
  };
  const writer = new McapWriter({
    writable,
    useChunks: chunking === 'zstd',
    chunkSize: 32 * 1024,
    compressChunk: (data) => ({ compression: 'zstd', compressedData: zstd.compress(data, 3) }),
  });
  const lines = [];
  const text = (s) => new TextEncoder().encode(s);
  await writer.start({ profile: 'theirs', library: '@mcap/core' });
  const imu = await writer.registerSchema({ name: 'px4.Imu', encoding: 'jsonschema', data: text('{}') });
  const pose = await writer.registerSchema({ name: 'geometry.Pose', encoding: 'protobuf', data: text('pb') });
  const channels = [
    [imu, '/imu', 'json', new Map([['rate_hz', '250']])],
    [pose, '/pose', 'protobuf', new Map()],
    [0, '/log', 'raw', new Map([['a', 'b'], ['c', 'd']])],
  ];
  const ids = [];
  for (const [schemaId, topic, encoding, metadata] of channels) {
    const id = await writer.registerChannel({ schemaId, topic, messageEncoding: encoding, metadata });
    ids.push(id);
    const schema = schemaId === imu ? 'px4.Imu' : schemaId === pose ? 'geometry.Pose' : '-';
    lines.push(`channel ${id} ${schemaId} ${topic} ${encoding} ${schema} ${metadata.size}`);
  }
  await writer.addMetadata({ name: 'session', metadata: new Map([['site', 'lab'], ['pilot', 'x']]) });
  lines.push('metadata session 2');
  const attachment = new Uint8Array(777).fill(42);
  const addAttachment = async () => {
    await writer.addAttachment({ name: 'map.bin', mediaType: 'application/octet-stream',
                                 logTime: 5n, createTime: 6n, data: attachment });
    lines.push('attachment map.bin application/octet-stream 777');
  };
  // @mcap/core 2.2.2 without chunks keeps messages in its buffer and indexes an attachment that
  // follows them at the offset before them (hq::mcap reports "the summary's index points at no
  // Attachment record"): there, the attachment goes first.
  if (chunking !== 'zstd') await addAttachment();
  const sequences = [0, 0, 0];
  for (let i = 0; i < 3000; i++) {
    const c = i % 7 === 0 ? 1 : i % 50 === 0 ? 2 : 0;
    const n = c === 1 ? 900 + (i % 13) * 50 : c === 2 ? i % 5 : 64;
    const data = new Uint8Array(n);
    let sum = 0;
    for (let k = 0; k < n; k++) {
      data[k] = (i * 31 + k * 17) & 0xff;
      sum = (sum + data[k]) >>> 0;
    }
    const logTime = 1_600_000_000_000_000_000n + BigInt(i) * 4_000_000n;
    const publishTime = logTime - BigInt(c * 100 + 7);
    const sequence = sequences[c]++;
    await writer.addMessage({ channelId: ids[c], sequence, logTime, publishTime, data });
    lines.push(`message ${ids[c]} ${sequence} ${logTime} ${publishTime} ${n} ${sum}`);
  }
  if (chunking === 'zstd') await addAttachment();
  await writer.end();
  lines.push(`statistics ${writer.statistics.messageCount} ${writer.statistics.chunkCount}`);
  fs.writeFileSync(mcapPath, Buffer.concat(parts));
  fs.writeFileSync(jsonPath, lines.join('\n') + '\n');
  console.log(`${path.basename(mcapPath)}: @mcap/core wrote ${writer.statistics.messageCount} ` +
              `messages in ${writer.statistics.chunkCount} chunks, ${size} bytes`);
}

(async () => {
  try {
    if (mode === 'write') {
      await write();
    } else {
      const handlers = await loadDecompressHandlers();
      await indexed(handlers);
      streamed(handlers);
    }
  } catch (e) {
    fail(`@mcap/core threw: ${e.stack || e}`);
  }
  if (failures > 0) {
    console.error(`${name || mcapPath}: ${failures} failure(s)`);
    process.exit(1);
  }
})();
