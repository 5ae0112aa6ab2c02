// Decodes the raw CDR a vehicle with --ros2 published (dumped by hq_ros2_probe) with an
// independent ROS 2 decoder: @foxglove/rosmsg parses the ROS 2 .msg definitions below (the
// ROS 2 message texts, comments and constants left out), @foxglove/rosmsg2-serialization reads
// the CDR. A field out of place, a wrong type or a non-XCDR1 encoding fails the decode or the
// checks of plausible values: frame ids, increasing stamps, unit quaternions, and the odometry's
// twist equal to the native state's v_H in the ROS body frame FLU.
// Usage: node decode_ros2.cjs NODE_MODULES DUMP_DIR NAMESPACE
'use strict';
const path = require('path');
const fs = require('fs');
const [modules, dir, ns] = process.argv.slice(2);
const { parse } = require(path.join(modules, '@foxglove/rosmsg'));
const { MessageReader } = require(path.join(modules, '@foxglove/rosmsg2-serialization'));

const SEP = '\n================================================================================\n';
const MSGS = {
  'builtin_interfaces/Time': 'int32 sec\nuint32 nanosec',
  'std_msgs/Header': 'builtin_interfaces/Time stamp\nstring frame_id',
  'geometry_msgs/Vector3': 'float64 x\nfloat64 y\nfloat64 z',
  'geometry_msgs/Point': 'float64 x\nfloat64 y\nfloat64 z',
  'geometry_msgs/Quaternion': 'float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1',
  'geometry_msgs/Pose': 'Point position\nQuaternion orientation',
  'geometry_msgs/PoseWithCovariance': 'Pose pose\nfloat64[36] covariance',
  'geometry_msgs/Twist': 'Vector3 linear\nVector3 angular',
  'geometry_msgs/TwistWithCovariance': 'Twist twist\nfloat64[36] covariance',
  'geometry_msgs/Transform': 'Vector3 translation\nQuaternion rotation',
  'geometry_msgs/TransformStamped':
      'std_msgs/Header header\nstring child_frame_id\nTransform transform',
  'nav_msgs/Odometry':
      'std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n' +
      'geometry_msgs/TwistWithCovariance twist',
  'sensor_msgs/Imu':
      'std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n' +
      'float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n' +
      'float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n' +
      'float64[9] linear_acceleration_covariance',
  'sensor_msgs/CompressedImage': 'std_msgs/Header header\nstring format\nuint8[] data',
  'sensor_msgs/RegionOfInterest':
      'uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify',
  'sensor_msgs/CameraInfo':
      'std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n' +
      'float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n' +
      'uint32 binning_y\nRegionOfInterest roi',
  'sensor_msgs/PointField':
      'uint8 INT8=1\nuint8 INT16=2\nuint8 FLOAT32=7\nstring name\nuint32 offset\n' +
      'uint8 datatype\nuint32 count',
  'sensor_msgs/PointCloud2':
      'std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\n' +
      'bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense',
  'tf2_msgs/TFMessage': 'geometry_msgs/TransformStamped[] transforms',
  'rosgraph_msgs/Clock': 'builtin_interfaces/Time clock',
};

// The message text as rosbag2 stores it: the type's own, then every other type after a
// separator and "MSG: pkg/Type" (unused ones are harmless).
function reader(type) {
  let text = MSGS[type];
  for (const [name, body] of Object.entries(MSGS)) {
    if (name !== type) text += SEP + 'MSG: ' + name + '\n' + body;
  }
  return new MessageReader(parse(text, { ros2: true }));
}

function records(file) {
  const bytes = fs.readFileSync(path.join(dir, file));
  const out = [];
  for (let at = 0; at + 4 <= bytes.length;) {
    const n = bytes.readUInt32LE(at);
    out.push(bytes.subarray(at + 4, at + 4 + n));
    at += 4 + n;
  }
  return out;
}

let failures = 0;
function check(ok, what) {
  if (!ok) {
    console.log('FAIL: ' + what);
    ++failures;
  }
}
const stampNs = (s) => BigInt(s.sec) * 1000000000n + BigInt(s.nanosec ?? s.nsec);
function increasing(msgs, name) {
  for (let i = 1; i < msgs.length; ++i) {
    if (stampNs(msgs[i].header.stamp) <= stampNs(msgs[i - 1].header.stamp)) {
      check(false, `${name}: stamp ${i} not after stamp ${i - 1}`);
      return;
    }
  }
}
const unit = (q) => Math.abs(Math.hypot(q.x, q.y, q.z, q.w) - 1) < 1e-6;

// A type alone with what it uses (the full set leaves Twist, used unqualified by
// TwistWithCovariance, without its own definition when Twist is the top-level type).
function readerOf(text) {
  return new MessageReader(parse(text, { ros2: true }));
}

function decodeAll(file, type, min, makeReader = () => reader(type)) {
  const cdr = records(file);
  // XCDR1 little-endian (CDR_LE): the encapsulation rmw_cyclonedds writes and reads.
  for (const c of cdr) check(c[0] === 0 && c[1] === 1, `${file}: encapsulation ${c[0]} ${c[1]}`);
  const r = makeReader();
  const msgs = cdr.map((c) => r.readMessage(c));
  console.log(`${type}: ${msgs.length} decoded from ${file}`);
  check(msgs.length >= min, `${file}: ${msgs.length} samples, expected >= ${min}`);
  return msgs;
}

// Odometry: frames, stamps, the unknown pose marked, the twist = v_H in FLU (v_F_from_v_H).
const odom = decodeAll('odom.cdr', 'nav_msgs/Odometry', 20);
increasing(odom, 'odom');
const states = new Map();
for (const line of fs.readFileSync(path.join(dir, 'states.csv'), 'utf8').trim().split('\n').slice(1)) {
  const [t, vx, vy, vz, roll, pitch] = line.split(',');
  states.set(BigInt(t), { v: [+vx, +vy, +vz], roll: +roll, pitch: +pitch });
}
let compared = 0;
let moving = 0;
for (const o of odom) {
  check(o.header.frame_id === `${ns}/odom`, `odom frame_id ${o.header.frame_id}`);
  check(o.child_frame_id === `${ns}/base_link`, `odom child_frame_id ${o.child_frame_id}`);
  check(o.pose.covariance.length === 36 && (o.pose.covariance[0] === -1 ||
        (o.pose.covariance[0] >= 0 && o.pose.covariance[35] >= 0)),
        'odom pose.covariance: -1 before the odom pose, else its variances');
  check(unit(o.pose.pose.orientation), 'odom orientation is a unit quaternion');
  const s = states.get(stampNs(o.header.stamp));
  if (!s) continue;
  // v_B = R_H_B^T v_H, R_H_B = R_y(pitch) R_x(roll); v_F = (x, -y, -z).
  const [cr, sr, cp, sp] = [Math.cos(s.roll), Math.sin(s.roll), Math.cos(s.pitch), Math.sin(s.pitch)];
  const [x, y, z] = s.v;
  const bx = cp * x - sp * z;
  const by = sr * sp * x + cr * y + sr * cp * z;
  const bz = cr * sp * x - sr * y + cr * cp * z;
  const v = o.twist.twist.linear;
  const err = Math.hypot(v.x - bx, v.y + by, v.z + bz);
  check(err < 1e-4, `odom twist ${JSON.stringify(v)} vs state v_F (${bx}, ${-by}, ${-bz})`);
  ++compared;
  if (Math.hypot(x, y) > 0.05) ++moving;
}
console.log(`odom: twist checked against ${compared} native states, ${moving} of them moving`);
// The odom pose moves with the vehicle (no marker map in this world), its uncertainty growing.
const last = odom[odom.length - 1];
const p = last.pose.pose.position;
console.log(`odom: last pose (${p.x.toFixed(3)}, ${p.y.toFixed(3)}, ${p.z.toFixed(3)}) m ENU, ` +
            `sigma ${Math.sqrt(last.pose.covariance[0]).toFixed(3)} m, ` +
            `twist sigma x ${Math.sqrt(last.twist.covariance[0]).toFixed(4)} m/s`);
check(Math.hypot(p.x, p.y, p.z) > 0.1, 'odom: the pose never moved');
check(last.pose.covariance[0] > 0 && last.pose.covariance[35] > 0,
      'odom: position and yaw variances grow in flight');
check(last.twist.covariance[0] > 0, 'odom: the twist covariance is the estimator\'s, not zero');
check(compared >= 10, `odom: only ${compared} samples matched a native state by stamp`);
check(moving >= 1, 'odom: the vehicle never moved while odometry was recorded');

const imu = decodeAll('imu.cdr', 'sensor_msgs/Imu', 5);
increasing(imu, 'imu');
for (const m of imu) {
  check(m.header.frame_id === `${ns}/base_link`, `imu frame_id ${m.header.frame_id}`);
  check(m.linear_acceleration_covariance[0] === -1, 'imu: no acceleration, covariance[0] = -1');
  check(Math.abs(m.orientation_covariance[8] - Math.PI * Math.PI / 3) < 1e-3,
        'imu: the yaw is unknown (variance pi^2/3)');
  check(unit(m.orientation), 'imu orientation is a unit quaternion');
}

const tf = decodeAll('tf.cdr', 'tf2_msgs/TFMessage', 5);
for (const m of tf) {
  check(m.transforms.length === 1, 'tf: one transform');
  const t = m.transforms[0];
  check(t.header.frame_id === `${ns}/odom` && t.child_frame_id === `${ns}/base_link`,
        `tf ${t.header.frame_id} -> ${t.child_frame_id}`);
  check(unit(t.transform.rotation), 'tf rotation is a unit quaternion');
}

// /tf_static, read by a reader that joined seconds after it was written (transient local).
const statics = decodeAll('tf_static.cdr', 'tf2_msgs/TFMessage', 1);
for (const m of statics) {
  const names = m.transforms.map((t) => `${t.header.frame_id}->${t.child_frame_id}`).join(' ');
  check(names === `${ns}/base_link->${ns}/camera_link ${ns}/camera_link->${ns}/camera_optical`,
        `tf_static: ${names}`);
  for (const t of m.transforms) check(unit(t.transform.rotation), 'tf_static: unit quaternions');
}
console.log(`tf_static: ${statics.length} sample(s) to a late joiner: base_link -> camera_link ` +
            `at (${statics.length ? statics[0].transforms[0].transform.translation.x.toFixed(3) : '?'}, ...) m`);

const clouds = decodeAll('obstacles.cdr', 'sensor_msgs/PointCloud2', 1);
for (const c of clouds) {
  check(c.header.frame_id === `${ns}/base_link`, `cloud frame_id ${c.header.frame_id}`);
  check(c.fields.map((f) => `${f.name}:${f.offset}:${f.datatype}`).join(' ') ===
        'x:0:7 y:4:7 z:8:7', 'cloud fields x, y, z float32');
  check(c.height === 1 && c.point_step === 12 && c.row_step === 12 * c.width &&
        c.data.length === c.row_step, 'cloud sizes agree');
  const view = new DataView(c.data.buffer, c.data.byteOffset, c.data.byteLength);
  let finite = true;
  for (let i = 0; i < c.data.length; i += 4) finite = finite && isFinite(view.getFloat32(i, true));
  check(finite && c.width > 0, `cloud of ${c.width} finite points`);
}

const images = decodeAll('image.cdr', 'sensor_msgs/CompressedImage', 1);
for (const m of images) {
  check(m.format === 'jpeg' && m.data[0] === 0xff && m.data[1] === 0xd8, 'image is a JPEG');
  check(m.header.frame_id === `${ns}/camera_optical`, `image frame_id ${m.header.frame_id}`);
}
const infos = decodeAll('camera_info.cdr', 'sensor_msgs/CameraInfo', 1);
for (const m of infos) {
  check(m.width > 0 && m.height > 0 && m.k[0] > 0 && m.k[8] === 1 && m.d.length === 5,
        `camera_info ${m.width}x${m.height} fx ${m.k[0]}`);
}

// cmd_vel: the Twist the probe flew the vehicle with, as teleop_twist_keyboard sends it.
const cmds = decodeAll('cmd_vel.cdr', 'geometry_msgs/Twist', 5, () => readerOf(
    'geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular' + SEP +
    'MSG: geometry_msgs/Vector3\n' + MSGS['geometry_msgs/Vector3']));
for (const c of cmds) {
  check(Math.abs(Math.hypot(c.linear.x, c.linear.y) - 0.3) < 1e-6 && c.linear.z === 0 &&
        c.angular.z === 0, `cmd_vel ${JSON.stringify(c)}: 0.3 m/s along the heading`);
}

// /clock: the simulated time (use_sim_time), increasing, and the very stamps the topics carry.
const clocks = decodeAll('clock.cdr', 'rosgraph_msgs/Clock', 20);
const clockNs = clocks.map((c) => stampNs(c.clock));
for (let i = 1; i < clockNs.length; ++i) {
  if (clockNs[i] <= clockNs[i - 1]) {
    check(false, `clock ${i} not after clock ${i - 1}`);
    break;
  }
}
check(clockNs.length > 0 && clockNs[clockNs.length - 1] < 3600n * 1000000000n,
      'clock is the simulated time (under an hour), not the epoch');
const clockSet = new Set(clockNs.map(String));
const stamped = odom.filter((o) => clockSet.has(String(stampNs(o.header.stamp)))).length;
console.log(`clock: ${clocks.length} decoded; ${stamped} of ${odom.length} odom stamps are /clock times`);
check(stamped >= 10, `only ${stamped} odom stamps are /clock times`);

// mode_status: the vehicle's answers to the probe's mode texts (std_msgs/String).
const answers = decodeAll('mode_status.cdr', 'std_msgs/String', 4,
                          () => readerOf('string data')).map((m) => m.data);
for (const needle of ['refused: unknown mode', 'mode hover accepted', 'mode teleop accepted',
                      'does not command']) {
  check(answers.some((a) => a.includes(needle)), `mode_status: no answer with "${needle}"`);
}

// ros_discovery_info as rmw_dds_common (Iron+, Jazzy: Gid uint8[16]) defines it: the vehicle is
// node /haptiquad_1 with its readers and writers, each GUID under the participant's prefix.
const discovery = decodeAll('ros_discovery_info.cdr', 'rmw_dds_common/ParticipantEntitiesInfo', 1,
                        () => readerOf(
    'Gid gid\nNodeEntitiesInfo[] node_entities_info_seq' + SEP + 'MSG: rmw_dds_common/Gid\n' +
    'uint8[16] data' + SEP + 'MSG: rmw_dds_common/NodeEntitiesInfo\n' +
    'string<=256 node_namespace\nstring<=256 node_name\nGid[] reader_gid_seq\nGid[] writer_gid_seq'));
const info = discovery[0];
const hex = (g) => Buffer.from(g.data).toString('hex');
check(info.node_entities_info_seq.length === 1, 'ros_discovery_info: one node');
const node = info.node_entities_info_seq[0] || {reader_gid_seq: [], writer_gid_seq: []};
check(node.node_namespace === '/' && node.node_name === 'haptiquad_1',
      `ros_discovery_info: node ${node.node_namespace} ${node.node_name}`);
const gids = [...node.reader_gid_seq, ...node.writer_gid_seq].map(hex);
check(node.reader_gid_seq.length === 3 && node.writer_gid_seq.length === 9,
      `ros_discovery_info: ${node.reader_gid_seq.length} readers, ${node.writer_gid_seq.length} writers`);
check(new Set(gids).size === gids.length, 'ros_discovery_info: GIDs are distinct');
check(gids.every((g) => g.slice(0, 24) === hex(info.gid).slice(0, 24)),
      'ros_discovery_info: every GID is under the participant GUID prefix');
console.log(`ros_discovery_info: node ${node.node_namespace}${node.node_name}, ` +
            `${node.reader_gid_seq.length} readers, ${node.writer_gid_seq.length} writers`);

if (failures > 0) {
  console.log(`${failures} check(s) failed`);
  process.exit(1);
}
console.log('all ROS 2 topics decoded and plausible');
