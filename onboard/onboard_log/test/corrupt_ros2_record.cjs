// Copies a recorded ros2.mcap with @mcap/core's writer, damaging one thing, for the MCAP check's
// negative cases on a real record: `message` cuts the first message of TOPIC to half its bytes
// (a decoder runs out of data); `schema` misspells a type the schema of TOPIC uses, so its
// dependencies no longer resolve. Usage: node corrupt_ros2_record.cjs MODULES IN OUT MODE TOPIC
'use strict';
const fs = require('fs');
const path = require('path');
const [modules, inPath, outPath, mode, topic] = process.argv.slice(2);
const need = (name) => require(path.resolve(modules, name));
const { McapIndexedReader, McapWriter } = need('@mcap/core');
const { loadDecompressHandlers } = need('@mcap/support');

class FileWritable {
  constructor() { this.chunks = []; this.size = 0n; }
  position() { return this.size; }
  async write(buffer) { this.chunks.push(Buffer.from(buffer)); this.size += BigInt(buffer.byteLength); }
}

(async () => {
  const bytes = new Uint8Array(fs.readFileSync(inPath));
  const reader = await McapIndexedReader.Initialize({
    readable: { size: async () => BigInt(bytes.length),
                read: async (o, n) => bytes.subarray(Number(o), Number(o + n)) },
    decompressHandlers: await loadDecompressHandlers() });
  const out = new FileWritable();
  const writer = new McapWriter({ writable: out });
  await writer.start({ profile: reader.header.profile, library: 'corrupt_ros2_record.cjs' });
  const target = [...reader.channelsById.values()].find((c) => c.topic === topic);
  if (!target) throw new Error(`${inPath}: no channel ${topic}`);
  const schemaIds = new Map();
  for (const s of reader.schemasById.values()) {
    let data = s.data;
    if (mode === 'schema' && s.id === target.schemaId) {
      const text = new TextDecoder().decode(s.data);
      const damaged = text.replace('geometry_msgs/Twist twist', 'geometry_msgs/Twst twist');
      if (damaged === text) throw new Error(`${topic}: schema has no geometry_msgs/Twist field`);
      data = new TextEncoder().encode(damaged);
    }
    schemaIds.set(s.id, await writer.registerSchema({ name: s.name, encoding: s.encoding, data }));
  }
  const channelIds = new Map();
  for (const c of reader.channelsById.values()) {
    channelIds.set(c.id, await writer.registerChannel({
      topic: c.topic, schemaId: schemaIds.get(c.schemaId), messageEncoding: c.messageEncoding,
      metadata: c.metadata }));
  }
  let cut = false;
  for await (const m of reader.readMessages()) {
    let data = m.data;
    if (mode === 'message' && !cut && m.channelId === target.id) {
      data = m.data.subarray(0, Math.floor(m.data.length / 2));
      cut = true;
    }
    await writer.addMessage({ channelId: channelIds.get(m.channelId), sequence: m.sequence,
                              logTime: m.logTime, publishTime: m.publishTime, data });
  }
  await writer.end();
  fs.writeFileSync(outPath, Buffer.concat(out.chunks));
})().catch((e) => { console.error(e.stack || e); process.exit(1); });
