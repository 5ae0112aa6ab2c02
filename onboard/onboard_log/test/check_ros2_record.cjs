// A flight's ROS 2 bag (DIR/ros2.mcap) against what the vehicle published in the same flight
// (DIR/onboard.mcap), read by independent decoders: @foxglove/rosmsg parses each ros2msg schema
// and @foxglove/rosmsg2-serialization decodes every message; the link's vehicle states are
// decoded with their omgidl schema (@foxglove/omgidl-parser, -serialization). Checked:
//   - the "ros2" profile, cdr/ros2msg channels named as ROS names them, offered_qos_profiles
//     (/tf_static transient local), the bridge's topics all present;
//   - one Odometry, Imu and /tf per vehicle state, stamped with the state's time (simulated
//     time here, with /clock the same), its twist the state's v_H in base_link (FLU) and its
//     rates the state's gyro rates;
//   - /tf_static the camera mount onboard.mcap's foxglove /tf_static gives
//     (hq::geometry::ros_camera_frames), /tf's odom -> base_link the pose of foxglove /tf;
//   - every CompressedImage the JPEG onboard.mcap's image channel holds, in order;
//   - the per-topic counts the exit summary printed ("  ros2 record TOPIC N messages").
// Usage: node check_ros2_record.cjs MODULES onboard.mcap ros2.mcap SUMMARY.txt
'use strict';
const fs = require('fs');
const path = require('path');

const [modules, onboardPath, ros2Path, summaryPath] = process.argv.slice(2);
const need = (name) => require(path.resolve(modules, name));
const { McapIndexedReader } = need('@mcap/core');
const { loadDecompressHandlers } = need('@mcap/support');
const { parse: parseRosMsg } = need('@foxglove/rosmsg');
const { MessageReader: RosReader } = need('@foxglove/rosmsg2-serialization');
const { parseIDL } = need('@foxglove/omgidl-parser');
const { MessageReader: IdlReader } = need('@foxglove/omgidl-serialization');

let failures = 0;
function check(condition, message) {
  if (!condition) {
    if (failures < 20) console.error(`FAIL ${message}`);
    failures++;
  }
}
const close = (a, b, tolerance) => Math.abs(a - b) <= tolerance;
// builtin_interfaces/Time: @foxglove/rosmsg2-serialization names its second field nsec.
const stampNs = (t) => BigInt(t.sec) * 1000000000n + BigInt(t.nanosec ?? t.nsec);

async function open(file, handlers) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  return McapIndexedReader.Initialize({ readable, decompressHandlers: handlers });
}

// Every message of a file by topic, decoded with `decoderOf(channel, schema)`.
async function readAll(reader, decoderOf) {
  const decoders = new Map();
  for (const [id, c] of reader.channelsById) {
    decoders.set(id, decoderOf(c, reader.schemasById.get(c.schemaId)));
  }
  const byTopic = new Map();
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const c = reader.channelsById.get(m.channelId);
    const decode = decoders.get(m.channelId);
    if (!byTopic.has(c.topic)) byTopic.set(c.topic, []);
    byTopic.get(c.topic).push({ logTime: m.logTime, msg: decode ? decode(m.data) : undefined });
  }
  return byTopic;
}

// v_F of the bridge: v_B = (R_y(pitch) R_x(roll))^T v_H, then FRD -> FLU.
function vF(vH, roll, pitch) {
  const [cr, sr, cp, sp] = [Math.cos(roll), Math.sin(roll), Math.cos(pitch), Math.sin(pitch)];
  // R = R_y(p) R_x(r) = [[cp, sp sr, sp cr], [0, cr, -sr], [-sp, cp sr, cp cr]]; v_B = R^T v_H.
  const x = cp * vH.x - sp * vH.z;
  const y = sp * sr * vH.x + cr * vH.y + cp * sr * vH.z;
  const z = sp * cr * vH.x - sr * vH.y + cp * cr * vH.z;
  return { x, y: -y, z: -z };
}

(async () => {
  const handlers = await loadDecompressHandlers();
  const ros2 = await open(ros2Path, handlers);
  const onboard = await open(onboardPath, handlers);
  check(ros2.header.profile === 'ros2', `profile "${ros2.header.profile}", expected "ros2"`);
  const topics = new Map();
  for (const c of ros2.channelsById.values()) {
    const s = ros2.schemasById.get(c.schemaId);
    topics.set(c.topic, s.name);
    check(c.messageEncoding === 'cdr' && s.encoding === 'ros2msg',
          `${c.topic}: ${c.messageEncoding}/${s.encoding}, expected cdr/ros2msg`);
    check(!c.topic.startsWith('rt/') && c.topic.startsWith('/'), `${c.topic}: not a ROS name`);
    const qos = c.metadata.get('offered_qos_profiles') || '';
    check(/reliability: 1/.test(qos) && /history: 1/.test(qos), `${c.topic}: offered_qos_profiles "${qos}"`);
    check(/durability: 1\b/.test(qos) === (c.topic === '/tf_static'),
          `${c.topic}: durability in "${qos}" (transient local for /tf_static only)`);
  }
  const odomTopic = [...topics.keys()].find((t) => t.endsWith('/odom'));
  const ns = odomTopic ? odomTopic.slice(1, -'/odom'.length) : 'none';
  // Every topic the bridge publishes in this flight (the obstacle cloud only when a state
  // carried points: a channel appears with its first message).
  const expected = {
    '/clock': 'rosgraph_msgs/msg/Clock', '/tf_static': 'tf2_msgs/msg/TFMessage',
    '/tf': 'tf2_msgs/msg/TFMessage', [`/${ns}/odom`]: 'nav_msgs/msg/Odometry',
    [`/${ns}/imu`]: 'sensor_msgs/msg/Imu', [`/${ns}/obstacles`]: 'sensor_msgs/msg/PointCloud2',
    [`/${ns}/camera/image/compressed`]: 'sensor_msgs/msg/CompressedImage',
    [`/${ns}/camera/camera_info`]: 'sensor_msgs/msg/CameraInfo',
  };
  for (const [topic, type] of Object.entries(expected)) {
    if (topic.endsWith('/obstacles') && !topics.has(topic)) continue;  // checked below
    check(topics.get(topic) === type, `${topic}: type ${topics.get(topic)}, expected ${type}`);
  }
  for (const topic of topics.keys()) check(topic in expected, `${topic}: not a topic the bridge publishes`);

  const rosMsgs = await readAll(ros2, (c, s) => {
    const reader = new RosReader(parseRosMsg(new TextDecoder().decode(s.data), { ros2: true }));
    return (data) => reader.readMessage(data);
  });
  const native = await readAll(onboard, (c, s) => {
    if (c.messageEncoding === 'cdr' && c.topic === '/hq/vehicle_state') {
      const reader = new IdlReader(s.name, parseIDL(new TextDecoder().decode(s.data)));
      return (data) => reader.readMessage(data);
    }
    if (c.messageEncoding === 'json') return (data) => JSON.parse(new TextDecoder().decode(data));
    return undefined;
  });
  const get = (map, topic) => map.get(topic) || [];
  let previous = 0n;
  for (const list of [...rosMsgs.values()].flat().sort((a, b) => (a.logTime < b.logTime ? -1 : 1))) {
    check(list.logTime >= previous, 'log time went back');
    previous = list.logTime;
  }

  // Per state: odom, imu, /tf and /clock, in order.
  const states = get(native, '/hq/vehicle_state');
  const odoms = get(rosMsgs, `/${ns}/odom`);
  const imus = get(rosMsgs, `/${ns}/imu`);
  const tfs = get(rosMsgs, '/tf');
  const clocks = get(rosMsgs, '/clock');
  check(states.length > 0, 'onboard.mcap: no vehicle states');
  for (const [name, list] of [['odom', odoms], ['imu', imus], ['/tf', tfs], ['/clock', clocks]]) {
    check(list.length === states.length, `${name}: ${list.length} messages for ${states.length} states`);
  }
  const foxTf = get(native, '/tf');
  check(foxTf.length === states.length, `foxglove /tf: ${foxTf.length} for ${states.length} states`);
  const n = Math.min(states.length, odoms.length, imus.length, tfs.length, clocks.length, foxTf.length);
  for (let i = 0; i < n; ++i) {
    const s = states[i].msg;
    const o = odoms[i].msg;
    check(stampNs(o.header.stamp) === BigInt(s.t_ns), `odom ${i}: stamp ${stampNs(o.header.stamp)}, state t_ns ${s.t_ns}`);
    check(stampNs(clocks[i].msg.clock) === BigInt(s.t_ns), `/clock ${i}: not the state's time`);
    check(o.header.frame_id === `${ns}/odom` && o.child_frame_id === `${ns}/base_link`,
          `odom ${i}: frames ${o.header.frame_id} -> ${o.child_frame_id}`);
    const v = vF(s.v_H_mps, s.roll_rad, s.pitch_rad);
    const t = o.twist.twist.linear;
    check(close(t.x, v.x, 1e-9) && close(t.y, v.y, 1e-9) && close(t.z, v.z, 1e-9),
          `odom ${i}: twist ${JSON.stringify(t)}, the state's velocity in base_link ${JSON.stringify(v)}`);
    const w = o.twist.twist.angular;
    const g = s.omega_B_radps;
    check(close(w.x, g.x, 1e-9) && close(w.y, -g.y, 1e-9) && close(w.z, -g.z, 1e-9),
          `odom ${i}: angular ${JSON.stringify(w)}, gyro ${JSON.stringify(g)}`);
    const imu = imus[i].msg;
    check(stampNs(imu.header.stamp) === BigInt(s.t_ns) && close(imu.angular_velocity.z, w.z, 0),
          `imu ${i}: not the state's`);
    const tr = tfs[i].msg.transforms[0];
    const fox = foxTf[i].msg;
    check(tr.header.frame_id === `${ns}/odom` && tr.child_frame_id === `${ns}/base_link`,
          `/tf ${i}: ${tr.header.frame_id} -> ${tr.child_frame_id}`);
    for (const k of ['x', 'y', 'z']) {
      check(close(tr.transform.translation[k], fox.translation[k], 1e-6) &&
            close(tr.transform.translation[k], o.pose.pose.position[k], 0),
            `/tf ${i}: translation.${k} ${tr.transform.translation[k]}, foxglove /tf ${fox.translation[k]}`);
    }
  }

  // /tf_static: once, the mount's two transforms, as onboard.mcap's foxglove ones.
  const statics = get(rosMsgs, '/tf_static');
  check(statics.length === 1, `/tf_static: ${statics.length} messages, expected 1`);
  const foxStatic = get(native, '/tf_static').slice(0, 2).map((m) => m.msg);
  if (statics.length > 0 && foxStatic.length === 2) {
    const ts = statics[0].msg.transforms;
    check(ts.length === 2, `/tf_static: ${ts.length} transforms`);
    const names = [['base_link', 'camera_link'], ['camera_link', 'camera_optical']];
    for (let j = 0; j < Math.min(2, ts.length); ++j) {
      check(ts[j].header.frame_id === `${ns}/${names[j][0]}` && ts[j].child_frame_id === `${ns}/${names[j][1]}`,
            `/tf_static ${j}: ${ts[j].header.frame_id} -> ${ts[j].child_frame_id}`);
      check(foxStatic[j].parent_frame_id === names[j][0], `foxglove /tf_static ${j}: ${foxStatic[j].parent_frame_id}`);
      for (const k of ['x', 'y', 'z']) {
        check(close(ts[j].transform.translation[k], foxStatic[j].translation[k], 1e-7),
              `/tf_static ${j}: translation.${k} ${ts[j].transform.translation[k]} vs ${foxStatic[j].translation[k]}`);
      }
      for (const k of ['x', 'y', 'z', 'w']) {
        check(close(ts[j].transform.rotation[k], foxStatic[j].rotation[k], 1e-7),
              `/tf_static ${j}: rotation.${k} ${ts[j].transform.rotation[k]} vs ${foxStatic[j].rotation[k]}`);
      }
    }
  }

  // Images: the same JPEG bytes, in order, with a CameraInfo each.
  const images = get(rosMsgs, `/${ns}/camera/image/compressed`);
  const foxImages = get(native, '/camera/image/compressed');
  check(images.length > 0 && images.length === foxImages.length,
        `images: ${images.length}, onboard.mcap ${foxImages.length}`);
  for (let i = 0; i < Math.min(images.length, foxImages.length); ++i) {
    const jpeg = Buffer.from(foxImages[i].msg.data, 'base64');
    check(Buffer.compare(Buffer.from(images[i].msg.data), jpeg) === 0, `image ${i}: bytes differ`);
    check(images[i].msg.format === 'jpeg' && images[i].msg.header.frame_id === `${ns}/camera_optical`,
          `image ${i}: format ${images[i].msg.format}, frame ${images[i].msg.header.frame_id}`);
  }
  const infos = get(rosMsgs, `/${ns}/camera/camera_info`);
  check(infos.length === images.length, `camera_info: ${infos.length} for ${images.length} images`);
  if (infos.length > 0) {
    const k = infos[0].msg.k;
    check(k[0] > 0 && k[4] > 0 && k[8] === 1 && infos[0].msg.width > 0, `camera_info: K ${k}`);
  }
  // A cloud per state that carries obstacle points (the bridge sends none for an empty one).
  const clouds = get(rosMsgs, `/${ns}/obstacles`);
  const withPoints = states.filter((s) => s.msg.obstacle_points_B_m.length > 0);
  check(clouds.length === withPoints.length,
        `obstacles: ${clouds.length} clouds, ${withPoints.length} states with points`);
  for (let i = 0; i < Math.min(clouds.length, withPoints.length); ++i) {
    const c = clouds[i].msg;
    const p = withPoints[i].msg.obstacle_points_B_m;
    check(c.width === p.length && c.data.length === 12 * p.length, `cloud ${i}: ${c.width} points, state ${p.length}`);
    const view = new DataView(c.data.buffer, c.data.byteOffset, c.data.byteLength);
    check(view.getFloat32(0, true) === p[0].x && view.getFloat32(4, true) === -p[0].y,
          `cloud ${i}: first point not the state's in FLU`);
  }

  // The exit summary's counts are what the file holds.
  const text = fs.readFileSync(summaryPath, 'utf8');
  let lines = 0;
  for (const [, topic, count] of text.matchAll(/^  ros2 record (\S+) +(\d+) messages$/gm)) {
    lines++;
    check(get(rosMsgs, topic).length === Number(count), `${topic}: read ${get(rosMsgs, topic).length}, reported ${count}`);
  }
  check(lines === ros2.channelsById.size, `${lines} summary lines for ${ros2.channelsById.size} channels`);
  console.log(`${path.basename(ros2Path)}: ${[...rosMsgs.values()].flat().length} messages on ` +
              `${ros2.channelsById.size} channels (namespace ${ns}), ${states.length} vehicle states ` +
              `compared, ${images.length} images compared`);
  if (failures > 0) {
    console.error(`${failures} failure(s)`);
    process.exit(1);
  }
})().catch((e) => {
  console.error(`${ros2Path}: ${e.stack || e}`);
  process.exit(1);
});
