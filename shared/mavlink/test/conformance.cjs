// The node-mavlink side of the conformance check (run by conformance.sh).
//   node conformance.cjs MODULES decode FRAMES JSON   node-mavlink parses the frames our codec
//       wrote and checks every field against JSON; it also re-encodes each message and expects
//       the very bytes our encoder produced (field order, zero trimming, CRC_EXTRA).
//   node conformance.cjs MODULES encode FRAMES TEXT   node-mavlink encodes every message (v2,
//       two signed, one v1) and writes the values for hq-mavlink-conformance to check.
//   node conformance.cjs MODULES targets JSON         checks the router's table: each message's
//       name, CRC_EXTRA and the payload offsets of target_system (or MANUAL_CONTROL's target)
//       and target_component against node-mavlink's definitions.
'use strict';
const fs = require('fs');
const path = require('path');

const [modules, mode, framesPath, valuesPath] = process.argv.slice(2);
const mavlink = require(path.resolve(modules, 'node-mavlink'));
const { minimal, common, MavLinkPacketSplitter, MavLinkPacketParser, MavLinkProtocolV1,
        MavLinkProtocolV2, MavLinkPacketSignature } = mavlink;
const REGISTRY = { ...minimal.REGISTRY, ...common.REGISTRY };

let failures = 0;
function fail(message) {
  console.error(message);
  failures++;
}

function sameValue(field, expected, got) {
  const base = field.type.replace('[]', '');
  const one = (e, g) => {
    if (base === 'float' || base === 'double') return Math.fround(Number(e)) === g;
    if (base === 'uint64_t' || base === 'int64_t') return BigInt(e) === BigInt(g);
    return Number(e) === g;
  };
  if (field.type === 'char[]') return expected === got;
  if (field.type.endsWith('[]')) {
    return Array.isArray(expected) && expected.length === got.length &&
        expected.every((e, i) => one(e, got[i]));
  }
  return one(expected, got);
}

function show(value) {
  return JSON.stringify(value, (k, v) => (typeof v === 'bigint' ? v.toString() : v));
}

function decode() {
  const bytes = fs.readFileSync(framesPath);
  const expected = JSON.parse(fs.readFileSync(valuesPath, 'utf8'));
  const packets = [];
  const splitter = new MavLinkPacketSplitter();
  const parser = splitter.pipe(new MavLinkPacketParser());
  parser.on('data', (packet) => packets.push(packet));
  parser.on('end', () => {
    if (packets.length !== expected.length) {
      fail(`node-mavlink parsed ${packets.length} packets, expected ${expected.length}`);
    }
    let fieldCount = 0;
    packets.forEach((packet, i) => {
      const want = expected[i];
      if (!want) return;
      const where = `message ${i} (id ${want.msgid})`;
      const h = packet.header;
      if (h.msgid !== want.msgid || h.sysid !== want.sysid || h.compid !== want.compid ||
          h.payloadLength !== want.payload_length) {
        fail(`${where}: header ${show(h)} differs from ${show(want)}`);
        return;
      }
      const clazz = REGISTRY[h.msgid];
      const data = packet.protocol.data(packet.payload, clazz);
      const seen = new Set();
      for (const field of clazz.FIELDS) {
        seen.add(field.source);
        if (!(field.source in want.fields)) {
          fail(`${where}: field ${field.source} missing from our values`);
          continue;
        }
        fieldCount++;
        if (!sameValue(field, want.fields[field.source], data[field.name])) {
          fail(`${where}: ${field.source} decoded ${show(data[field.name])}, expected ` +
               `${show(want.fields[field.source])}`);
        }
      }
      for (const name of Object.keys(want.fields)) {
        if (!seen.has(name)) fail(`${where}: our field ${name} is not in node-mavlink's ${clazz.MSG_NAME}`);
      }
      // Byte-exact: node-mavlink encoding the decoded values must give our frame.
      const again = new MavLinkProtocolV2(h.sysid, h.compid).serialize(data, h.seq);
      if (!again.equals(packet.buffer)) {
        fail(`${where}: node-mavlink encodes ${again.toString('hex')}, our codec wrote ` +
             `${packet.buffer.toString('hex')}`);
      }
    });
    console.log(`node-mavlink decoded ${packets.length} frames of our codec, ${fieldCount} fields ` +
                `checked, byte-exact re-encoding compared; ${failures} failures`);
    process.exit(failures === 0 ? 0 : 1);
  });
  splitter.end(bytes);
}

// Values node chooses, by common.xml field name; every field non-zero where the type allows.
const VALUES = [
  ['HEARTBEAT', { custom_mode: 20, type: 2, autopilot: 3, base_mode: 0x81 | 0x40,
                  system_status: 5, mavlink_version: 3 }],
  ['SYS_STATUS', { onboard_control_sensors_present: 0x7FFFFFFF, onboard_control_sensors_enabled: 3,
                   onboard_control_sensors_health: 0x80000001, load: 999, voltage_battery: 65535,
                   current_battery: -32768, drop_rate_comm: 10000, errors_comm: 1,
                   errors_count1: 2, errors_count2: 3, errors_count3: 4, errors_count4: 5,
                   battery_remaining: 100, onboard_control_sensors_present_extended: 6,
                   onboard_control_sensors_enabled_extended: 7,
                   onboard_control_sensors_health_extended: 8 }],
  ['ATTITUDE', { time_boot_ms: 1, roll: 0.1, pitch: -0.2, yaw: 3.1, rollspeed: 1e-3,
                 pitchspeed: -1e-3, yawspeed: 0.7 }],
  ['COMMAND_LONG', { param1: 0, param2: 1, param3: 2.5, param4: -3.5, param5: 47.397742,
                     param6: 8.545594, param7: 488.1, command: 400, target_system: 1,
                     target_component: 1, confirmation: 1 }],
  ['COMMAND_ACK', { command: 176, result: 4, progress: 100, result_param2: -17,
                    target_system: 255, target_component: 190 }],
  ['SET_ATTITUDE_TARGET', { time_boot_ms: 4294967295, q: [0.5, -0.5, 0.5, -0.5],
                            body_roll_rate: 1.5, body_pitch_rate: -1.5, body_yaw_rate: 0.3,
                            thrust: 0.71, target_system: 1, target_component: 1, type_mask: 3,
                            thrust_body: [0.01, -0.02, -0.9] }],
  ['VISION_SPEED_ESTIMATE', { usec: 123456789012345n, x: -0.3, y: 0.4, z: -0.05,
                              covariance: [0.01, 0.001, 0, 0.001, 0.02, 0, 0, 0, 0.03],
                              reset_counter: 200 }],
  ['HIGHRES_IMU', { time_usec: 9007199254740993n, xacc: 0.3, yacc: -0.4, zacc: -9.7,
                    xgyro: 0.05, ygyro: -0.06, zgyro: 0.07, xmag: 0.2, ymag: 0.01, zmag: -0.4,
                    abs_pressure: 950.5, diff_pressure: 0.25, pressure_alt: 512.75,
                    temperature: 41.5, fields_updated: 0x0FFF, id: 1 }],
  ['STATUSTEXT', { severity: 3, text: 'PreArm: node-mavlink says hello', id: 77, chunk_seq: 1 }],
  ['TIMESYNC', { tc1: 1234567890123456789n, ts1: -987654321n, target_system: 1,
                 target_component: 191 }],
  ['ODOMETRY', { time_usec: 1700000000000001n, x: 0.5, y: -1.5, z: -2.25,
                 q: [0.9238795, 0, 0, 0.3826834], vx: -0.3, vy: 0.2, vz: -0.1, rollspeed: 0.05,
                 pitchspeed: -0.06, yawspeed: 0.7,
                 pose_covariance: Array.from({ length: 21 }, (_, i) => 0.01 * (i + 1)),
                 velocity_covariance: Array.from({ length: 21 }, (_, i) => -0.003 * (i + 1)),
                 frame_id: 20, child_frame_id: 12, reset_counter: 17, estimator_type: 3,
                 quality: -1 }],
  ['PARAM_REQUEST_READ', { param_index: -1, target_system: 1, target_component: 1,
                           param_id: 'MPC_LAND_SPEED' }],
  ['PARAM_REQUEST_LIST', { target_system: 1, target_component: 0 }],
  ['PARAM_VALUE', { param_value: 2.5, param_count: 65535, param_index: 65534,
                    param_id: 'COM_OBC_LOSS_T', param_type: 9 }],
  ['PARAM_SET', { param_value: -0.75, target_system: 1, target_component: 1,
                  param_id: 'SIXTEEN_CHARS_ID', param_type: 9 }],
];

function encode() {
  const byName = {};
  for (const clazz of Object.values(REGISTRY)) byName[clazz.MSG_NAME] = clazz;
  const frames = [];
  const lines = [];
  let seq = 0;
  const add = (name, values, kind) => {
    const clazz = byName[name];
    const msg = new clazz();
    for (const field of clazz.FIELDS) {
      if (!(field.source in values)) throw new Error(`${name}.${field.source} has no value`);
      msg[field.name] = values[field.source];
    }
    const sysid = 1 + (seq % 3);
    const compid = kind === 'v1' ? 1 : 200 + seq;
    let buffer;
    if (kind === 'v1') {
      buffer = new MavLinkProtocolV1(sysid, compid).serialize(msg, seq);
    } else if (kind === 'signed') {
      const protocol = new MavLinkProtocolV2(sysid, compid, MavLinkProtocolV2.IFLAG_SIGNED);
      buffer = protocol.sign(protocol.serialize(msg, seq), 5, MavLinkPacketSignature.key('hq'));
    } else {
      buffer = new MavLinkProtocolV2(sysid, compid).serialize(msg, seq);
    }
    seq++;
    frames.push(buffer);
    lines.push(`message ${clazz.MSG_ID} ${sysid} ${compid} ${kind}`);
    for (const field of clazz.FIELDS) {
      let v = msg[field.name];
      if (kind === 'v1' && field.extension) continue;
      const f = (x) => (field.type.startsWith('float') ? Math.fround(x) : x).toString();
      lines.push(`${field.source} ${Array.isArray(v) ? v.map(f).join(' ') : field.type === 'char[]' ? v : f(v)}`);
    }
  };
  // By name, not by position: VALUES grows as messages are added.
  const valuesOf = (name) => VALUES.find(([n]) => n === name)[1];
  for (const [name, values] of VALUES) add(name, values, 'v2');
  add('HEARTBEAT', valuesOf('HEARTBEAT'), 'signed');
  add('ATTITUDE', valuesOf('ATTITUDE'), 'v1');
  // Trailing zeros: node trims them too; our parser pads them back.
  add('HIGHRES_IMU', { ...valuesOf('HIGHRES_IMU'), id: 0, fields_updated: 0, temperature: 0 }, 'v2');
  // The older TIMESYNC (no targets, trimmed to 16 bytes) as an older autopilot answers, and a
  // signed ODOMETRY whose quality and frames are the defaults a minimal sender leaves.
  add('TIMESYNC', { ...valuesOf('TIMESYNC'), target_system: 0, target_component: 0 }, 'v2');
  add('ODOMETRY', { ...valuesOf('ODOMETRY'), quality: 0, reset_counter: 0, estimator_type: 0 },
      'signed');
  fs.writeFileSync(framesPath, Buffer.concat(frames));
  fs.writeFileSync(valuesPath, lines.join('\n') + '\n');
  console.log(`node-mavlink encoded ${frames.length} frames (two signed, one v1)`);
}

function targets() {
  const table = JSON.parse(fs.readFileSync(framesPath, 'utf8'));
  for (const entry of table) {
    const clazz = REGISTRY[entry.msgid];
    if (!clazz) {
      fail(`${entry.name} (${entry.msgid}): not in node-mavlink's common.xml`);
      continue;
    }
    const offset = (...names) => {
      const field = clazz.FIELDS.find((f) => names.includes(f.source));
      return field ? field.offset : -1;
    };
    const theirs = { name: clazz.MSG_NAME, crc_extra: clazz.MAGIC_NUMBER,
                     target_system: offset('target_system', 'target'),
                     target_component: offset('target_component') };
    for (const key of Object.keys(theirs)) {
      if (theirs[key] !== entry[key]) {
        fail(`${entry.name} (${entry.msgid}): ${key} ${entry[key]}, node-mavlink has ${theirs[key]}`);
      }
    }
  }
  console.log(`node-mavlink checked ${table.length} routed messages (CRC_EXTRA, target offsets); ` +
              `${failures} failures`);
  process.exit(failures === 0 ? 0 : 1);
}

if (mode === 'decode') decode();
else if (mode === 'targets') targets();
else if (mode === 'encode') encode();
else {
  console.error('usage: node conformance.cjs MODULES decode|encode FRAMES VALUES | targets JSON');
  process.exit(2);
}
