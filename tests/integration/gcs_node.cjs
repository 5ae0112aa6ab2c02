// A ground control station made of node-mavlink (npm), an implementation that shares no code with
// ours, listening on UDP as QGroundControl does (run by gcs_process_test.sh):
//   node gcs_node.cjs MODULES PORT TIMEOUT_S
// It learns the vehicle's address from the first datagram, sends a GCS heartbeat each second,
// and passes when, through the companion, it has seen the FC's heartbeat and attitude and the
// companion's heartbeat and velocity (ODOMETRY, a broadcast; its TIMESYNC with the FC is not
// for the GCS), read every parameter with PARAM_REQUEST_LIST (each index once, the
// count right), set one with PARAM_SET (echoed with the new value) and read it back by name.
'use strict';
const dgram = require('dgram');
const path = require('path');

const [modules, portText, timeoutText] = process.argv.slice(2);
const mavlink = require(path.resolve(modules, 'node-mavlink'));
const { minimal, common, MavLinkPacketSplitter, MavLinkPacketParser, MavLinkProtocolV2 } = mavlink;
const REGISTRY = { ...minimal.REGISTRY, ...common.REGISTRY };
const byName = {};
for (const clazz of Object.values(REGISTRY)) byName[clazz.MSG_NAME] = clazz;

const kSystem = 255;
const kComponent = 190;
const protocol = new MavLinkProtocolV2(kSystem, kComponent);
let seq = 0;
let peer = null;
const socket = dgram.createSocket('udp4');

function send(name, values) {
  if (!peer) return;
  const clazz = byName[name];
  const msg = new clazz();
  for (const field of clazz.FIELDS) {
    msg[field.name] = field.source in values ? values[field.source] : msg[field.name];
  }
  socket.send(protocol.serialize(msg, seq++ & 0xff), peer.port, peer.address);
}

// What has been seen, and the steps of the parameter protocol.
const seen = { fcHeartbeat: 0, companionHeartbeat: 0, attitude: 0, companionOdometry: 0,
               companionTimesyncToFc: 0, unknown: 0 };
let step = 'wait';  // wait -> list -> set -> read -> done
let paramCount = -1;
const params = new Map();  // index -> {id, value}
const setId = 'MPC_LAND_SPEED';
const setValue = 0.7;
let echoed = null;
let readBack = null;
let failures = 0;
function fail(message) {
  console.error(`gcs_node: ${message}`);
  failures++;
}

function fields(packet) {
  const clazz = REGISTRY[packet.header.msgid];
  if (!clazz) {
    seen.unknown++;
    return null;
  }
  const data = packet.protocol.data(packet.payload, clazz);
  const out = {};
  for (const field of clazz.FIELDS) out[field.source] = data[field.name];
  return out;
}

function onPacket(packet) {
  const h = packet.header;
  const m = fields(packet);
  if (!m) return;
  if (h.msgid === 0) {
    if (h.sysid === 1 && h.compid === 1 && m.autopilot === 12) seen.fcHeartbeat++;
    if (h.sysid === 1 && h.compid === 191 && m.type === 18) seen.companionHeartbeat++;
  } else if (h.msgid === 30 && h.sysid === 1) {
    seen.attitude++;
  } else if (h.msgid === 331 && h.sysid === 1 && h.compid === 191) {
    seen.companionOdometry++;
  } else if (h.msgid === 111 && h.sysid === 1 && h.compid === 191 && m.target_system !== 0) {
    seen.companionTimesyncToFc++;  // addressed to the FC: the router must not send it here
  } else if (h.msgid === 22) {
    const id = m.param_id.replace(/\0.*$/, '');
    if (step === 'list') {
      if (paramCount >= 0 && m.param_count !== paramCount) {
        fail(`param_count changed from ${paramCount} to ${m.param_count}`);
      }
      paramCount = m.param_count;
      if (params.has(m.param_index)) fail(`parameter index ${m.param_index} sent twice`);
      params.set(m.param_index, { id, value: m.param_value });
    } else if (step === 'set' && id === setId) {
      echoed = m.param_value;
    } else if (step === 'read' && id === setId) {
      readBack = m.param_value;
    }
  }
}

const splitter = new MavLinkPacketSplitter();
const parser = splitter.pipe(new MavLinkPacketParser());
parser.on('data', onPacket);
let heartbeatsSent = 0;
function heartbeat() {
  if (!peer) return;
  send('HEARTBEAT', { type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4,
                      mavlink_version: 3 });
  heartbeatsSent++;
}
socket.on('message', (datagram, from) => {
  const first = !peer;
  peer = { address: from.address, port: from.port };
  if (first) heartbeat();  // as QGroundControl: say hello to a vehicle as soon as it is heard
  splitter.write(datagram);
});

function advance() {
  if (step === 'wait' && seen.fcHeartbeat > 0 && seen.attitude > 0) {
    step = 'list';
    send('PARAM_REQUEST_LIST', { target_system: 1, target_component: 1 });
  } else if (step === 'list' && paramCount > 0 && params.size === paramCount) {
    step = 'set';
    send('PARAM_SET', { target_system: 1, target_component: 1, param_id: setId,
                        param_value: setValue, param_type: 9 });
  } else if (step === 'set' && echoed !== null) {
    step = 'read';
    send('PARAM_REQUEST_READ', { target_system: 1, target_component: 1, param_id: setId,
                                 param_index: -1 });
  } else if (step === 'read' && readBack !== null) {
    step = 'done';
  }
}

function finish() {
  clearInterval(heartbeats);
  clearInterval(stepper);
  clearTimeout(deadline);
  const names = [...params.values()].map((p) => `${p.id}=${Math.fround(p.value).toPrecision(3)}`);
  console.log(`gcs_node: vehicle at ${peer ? `${peer.address}:${peer.port}` : 'never heard'}; ` +
              `FC heartbeats ${seen.fcHeartbeat}, companion heartbeats ${seen.companionHeartbeat}, ` +
              `attitude ${seen.attitude}, companion ODOMETRY ${seen.companionOdometry}, ` +
              `companion TIMESYNC addressed to the FC ${seen.companionTimesyncToFc}; parameters ${params.size} of ${paramCount}: ` +
              `${names.join(' ')}; ${setId} set ${setValue}, echoed ${echoed}, read back ${readBack}; ` +
              `GCS heartbeats sent ${heartbeatsSent}`);
  if (step !== 'done') fail(`stopped at step "${step}" (timeout)`);
  if (seen.fcHeartbeat < 3) fail('fewer than 3 FC heartbeats through the companion');
  if (seen.companionHeartbeat < 1) fail('no companion heartbeat');
  if (seen.companionOdometry < 1) fail('no companion ODOMETRY (a broadcast) through the router');
  if (seen.companionTimesyncToFc > 0) fail('the companion\'s TIMESYNC to the FC reached the GCS');
  for (let i = 0; i < paramCount; i++) {
    if (!params.has(i)) fail(`parameter index ${i} missing`);
  }
  if (paramCount !== 5) fail(`param_count ${paramCount}, hq-sim --sitl has 5 parameters`);
  if (echoed !== null && Math.abs(echoed - setValue) > 1e-6) fail(`PARAM_SET echoed ${echoed}`);
  if (readBack !== null && Math.abs(readBack - setValue) > 1e-6) fail(`read back ${readBack}`);
  console.log(failures === 0 ? 'gcs_node: passed' : `gcs_node: ${failures} failures`);
  socket.close();
  process.exit(failures === 0 ? 0 : 1);
}

const heartbeats = setInterval(heartbeat, 1000);
const stepper = setInterval(() => {
  advance();
  // Stay until heartbeats went both ways several times, not only the parameter round trip.
  if (step === 'done' && seen.fcHeartbeat >= 3 && heartbeatsSent >= 3) finish();
}, 100);
const deadline = setTimeout(finish, Number(timeoutText) * 1000);
socket.bind(Number(portText), '127.0.0.1', () => console.log(`gcs_node: listening on ${portText}`));
