// The live view: draws what the `view` node streams (Server-Sent Events `world` and `state`) on a canvas, and
// sends the page's actions as small JSON POSTs. Plain JS, no library: it has to work offline from the package.
'use strict';

const TRAIL_POINTS = 600;      // per robot at most; older points fade out and are dropped
const TRAIL_BUDGET = 20000;    // points of all trails together: a swarm's robots get shorter trails each
const NAME_MIN_PX = 6;         // a robot's name is drawn when its body is at least this radius on screen
const TRAIL_SPACING = 0.002;   // m between stored trail points
const TRAIL_JUMP = 0.1;        // m; a larger move between two frames (a reset) starts a new trail
const DRIVE_REPEAT_MS = 100;   // a held key re-sends its command, so the simulator's cmd_timeout never stops it
const COLOURS = ['#d62728', '#1f77b4', '#2ca02c', '#9467bd', '#ff7f0e', '#17becf', '#e377c2', '#8c564b'];

// Everything the page knows and what it last drew; `window.epuckView.drawn` is what tests compare with ROS.
const view = {
  // `?robot=NAME` in the page's address: the robot shown in detail from the start (a swarm's first robot is not read)
  world: null, worldText: null, frame: null, selected: new URLSearchParams(location.search).get('robot'), trails: {},
  drawn: null,   // {time, world: version, robots: {name: {pose: [x, y, yaw], stamp}}} of the last frame painted
  drive: {linear: 0.1, angular: 1.5, keys: new Set(), sent: '0,0', timer: null},
};
window.epuckView = view;

const $ = (id) => document.getElementById(id);
const canvas = $('arena');
const ctx = canvas.getContext('2d');
let drawPending = false;

// --- the stream --------------------------------------------------------------------------------------------

// The stream names the robot shown in detail: the view subscribes to its odometry and wheel speeds only.
let events = null;

function connect() {
  if (events) events.close();
  events = new EventSource(view.selected ? `/events?robot=${encodeURIComponent(view.selected)}` : '/events');
  events.onopen = () => setText('connection', 'live');
  events.onerror = () => setText('connection', 'disconnected: retrying…');
  events.addEventListener('world', onWorld);
  events.addEventListener('state', onState);
}

function onWorld(event) {
  if (event.data === view.worldText) return;   // the same world again (the stream reconnected)
  const world = JSON.parse(event.data);
  view.world = world;
  view.worldText = event.data;
  view.trails = {};
  const names = (world.robots || []).map((robot) => robot.name);
  // no robots yet (the view has no world): the selection, perhaps the address's, stays for the world to come
  const selected = names.includes(view.selected) || !names.length ? view.selected : names[0];
  $('robot').replaceChildren(...names.map((name) => new Option(name, name, false, name === selected)));
  if (selected !== view.selected) select(selected);
  requestDraw();
}

function onState(event) {
  view.frame = JSON.parse(event.data);
  const robots = Object.entries(view.frame.robots);
  const most = Math.min(TRAIL_POINTS, Math.floor(TRAIL_BUDGET / robots.length));
  for (const [name, robot] of robots) {
    if (robot.pose) extendTrail(name, robot.pose, most);
  }
  showFigures();
  requestDraw();
}

function extendTrail(name, pose, most) {
  const trail = view.trails[name] || (view.trails[name] = []);
  const last = trail[trail.length - 1];
  const moved = last ? Math.hypot(pose[0] - last[0], pose[1] - last[1]) : Infinity;
  if (moved > TRAIL_JUMP) trail.length = 0;
  if (moved >= TRAIL_SPACING) trail.push([pose[0], pose[1]]);
  if (trail.length > most) trail.splice(0, trail.length - most);
}

// --- figures -----------------------------------------------------------------------------------------------

function setText(id, text) { $(id).textContent = text; }
const fixed = (value, digits) => (value === null || value === undefined ? '–' : value.toFixed(digits));

function showFigures() {
  const frame = view.frame;
  setText('time', fixed(frame.time, 3));
  setText('rtf', fixed(frame.rtf, 2));
  setText('rtf-setting', frame.real_time_factor === null ? '–'
    : frame.real_time_factor === 0 ? 'max' : String(frame.real_time_factor));
  setText('collisions', frame.collisions === null ? '–' : String(frame.collisions));
  setText('run-state', frame.paused === null ? '–' : frame.paused ? 'paused' : 'running');
  $('pause').textContent = frame.paused ? 'Resume' : 'Pause';
  $('step').disabled = frame.paused === false;
  const robot = frame.robots[view.selected];
  if (!robot) return;
  setText('pose', robot.pose ? `${fixed(robot.pose[0], 3)} m, ${fixed(robot.pose[1], 3)} m, `
    + `${fixed(robot.pose[2] * 180 / Math.PI, 1)}°` : '–');
  setText('wheels', robot.wheel_speeds
    ? `${fixed(robot.wheel_speeds[0], 2)} / ${fixed(robot.wheel_speeds[1], 2)} rad/s` : '–');
  setText('odom-error', robot.odom_error
    ? `${fixed(robot.odom_error.distance * 1000, 1)} mm, ${fixed(robot.odom_error.yaw * 180 / Math.PI, 2)}°` : '–');
  setText('robot-collisions', robot.collisions === null ? '–' : String(robot.collisions));
  showCamera(robot);
}

const CAMERA_PERIOD = 200;   // ms between two camera images fetched: the page needs no more
let cameraShown = null;
let cameraFetched = 0;

function showCamera(robot) {
  const image = $('camera');
  if (robot.camera === null || robot.camera === undefined) {
    image.hidden = true;
    return;
  }
  const now = performance.now();
  if (robot.camera === cameraShown || now - cameraFetched < CAMERA_PERIOD) return;
  cameraShown = robot.camera;
  cameraFetched = now;
  image.src = `/camera?robot=${encodeURIComponent(view.selected)}&t=${robot.camera}`;
  image.hidden = false;
}

// --- drawing -----------------------------------------------------------------------------------------------

function requestDraw() {
  if (!drawPending) {
    drawPending = true;
    requestAnimationFrame(draw);   // at most once per screen refresh, however fast frames arrive
  }
}

function worldTransform() {
  const ratio = window.devicePixelRatio || 1;
  const width = canvas.clientWidth * ratio;
  const height = canvas.clientHeight * ratio;
  if (canvas.width !== width || canvas.height !== height) { canvas.width = width; canvas.height = height; }
  const [sizeX, sizeY] = view.world && view.world.arena ? view.world.arena : [1, 1];
  const margin = 0.06;
  const scale = Math.min(width / (sizeX + 2 * margin), height / (sizeY + 2 * margin));
  return {scale, cx: width / 2, cy: height / 2};
}

function draw() {
  drawPending = false;
  const t = worldTransform();
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.setTransform(t.scale, 0, 0, -t.scale, t.cx, t.cy);   // metres, x right, y up, origin at the centre
  if (view.world && view.world.arena) drawWorld(view.world, t.scale);
  const drawn = {time: view.frame ? view.frame.time : null, world: view.world ? view.world.version : null, robots: {}};
  if (view.world && view.frame) {
    (view.world.robots || []).forEach((start, index) => {
      const robot = view.frame.robots[start.name];
      if (!robot || !robot.pose) return;
      drawRobot(start.name, robot, COLOURS[index % COLOURS.length], t.scale);
      drawn.robots[start.name] = {pose: robot.pose, stamp: robot.stamp};
    });
  }
  view.drawn = drawn;
}

const rgb = (colour) => `rgb(${colour.map((c) => Math.round(255 * c)).join(', ')})`;

// The world as `bag plot` draws it: floor colour and paint, walls and obstacles in their colours, the lights.
function drawWorld(world, scale) {
  const [sizeX, sizeY] = world.arena;
  ctx.fillStyle = world.floor ? rgb(world.floor.color) : '#eeeee8';
  ctx.fillRect(-sizeX / 2, -sizeY / 2, sizeX, sizeY);
  if (world.floor) drawPaint(world.floor.paint, sizeX, sizeY);
  ctx.strokeStyle = world.wall_color ? rgb(world.wall_color) : '#8a8f96';
  ctx.lineWidth = 0.01;   // RectangleArena's wall thickness, outside the floor
  ctx.strokeRect(-sizeX / 2 - 0.005, -sizeY / 2 - 0.005, sizeX + 0.01, sizeY + 0.01);
  for (const box of world.boxes) {
    ctx.fillStyle = box.color ? rgb(box.color) : '#b7804d';
    ctx.save();
    ctx.translate(box.x, box.y);
    ctx.rotate(box.yaw);
    ctx.fillRect(-box.size_x / 2, -box.size_y / 2, box.size_x, box.size_y);
    ctx.restore();
  }
  for (const cylinder of world.cylinders) {
    ctx.fillStyle = cylinder.color ? rgb(cylinder.color) : '#7d8a96';
    ctx.beginPath();
    ctx.arc(cylinder.x, cylinder.y, cylinder.radius, 0, 2 * Math.PI);
    ctx.fill();
  }
  for (const light of world.lights || []) drawLight(light, scale);
}

// Paint in the world's order, later items over earlier ones, clipped to the floor (as the floor texture is).
function drawPaint(paint, sizeX, sizeY) {
  ctx.save();
  ctx.beginPath();
  ctx.rect(-sizeX / 2, -sizeY / 2, sizeX, sizeY);
  ctx.clip();
  for (const item of paint) {
    ctx.fillStyle = ctx.strokeStyle = rgb(item.color);
    ctx.beginPath();
    if (item.kind === 'disc') {
      ctx.arc(item.points[0][0], item.points[0][1], item.radius, 0, 2 * Math.PI);
      ctx.fill();
      continue;
    }
    item.points.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
    if (item.kind === 'polygon') {
      ctx.closePath();
      ctx.fill('evenodd');   // the floor texture's rule
    } else {   // a polyline: every point within width / 2 of it, so round ends and joins
      ctx.lineWidth = item.width;
      ctx.lineCap = ctx.lineJoin = 'round';
      ctx.stroke();
    }
  }
  ctx.restore();
}

// A point light: a gold star with a dark edge, a fixed size on screen.
function drawLight(light, scale) {
  const outer = 15 / scale;
  ctx.beginPath();
  for (let i = 0; i < 10; i++) {
    const radius = i % 2 ? outer * 0.45 : outer;
    const angle = Math.PI / 2 + i * Math.PI / 5;
    ctx.lineTo(light.x + radius * Math.cos(angle), light.y + radius * Math.sin(angle));
  }
  ctx.closePath();
  ctx.fillStyle = 'gold';
  ctx.fill();
  ctx.strokeStyle = '#333';
  ctx.lineWidth = 1.8 / scale;   // dark enough to show on the yellow paint a light often has under it
  ctx.lineJoin = 'miter';
  ctx.stroke();
}

function irColour(raw) {
  // Raw values run from the table's far end (nothing seen) to its near end (touching), roughly exponentially.
  const model = view.world.model;
  const level = Math.log(Math.max(raw, model.ir_raw_far) / model.ir_raw_far) / Math.log(model.ir_raw_near / model.ir_raw_far);
  return `hsl(${Math.round(120 * (1 - Math.min(level * 2.5, 1)))}, 85%, 42%)`;
}

function drawRobot(name, robot, colour, scale) {
  const model = view.world.model;
  const [x, y, yaw] = robot.pose;
  const trail = view.trails[name] || [];
  ctx.lineWidth = 3 / scale;
  ctx.strokeStyle = colour;
  for (let i = 1; i < trail.length; i++) {   // older segments fainter
    ctx.globalAlpha = 0.25 + 0.75 * i / trail.length;
    ctx.beginPath();
    ctx.moveTo(trail[i - 1][0], trail[i - 1][1]);
    ctx.lineTo(trail[i][0], trail[i][1]);
    ctx.stroke();
  }
  ctx.globalAlpha = 1;
  if (name === view.selected && robot.odom_error) {   // where odometry believes the robot is
    const [ox, oy] = robot.odom_error.odom_in_world;
    ctx.setLineDash([4 / scale, 3 / scale]);
    ctx.strokeStyle = '#555';
    ctx.beginPath();
    ctx.arc(ox, oy, model.body_radius, 0, 2 * Math.PI);
    ctx.stroke();
    ctx.setLineDash([]);
  }
  ctx.save();
  ctx.translate(x, y);
  ctx.rotate(yaw);
  if (robot.ir_range) {
    ctx.lineWidth = 1.5 / scale;
    model.sensor_poses.forEach(([sx, sy, syaw], i) => {
      ctx.strokeStyle = irColour(robot.ir_raw[i]);
      ctx.beginPath();
      ctx.moveTo(sx, sy);
      ctx.lineTo(sx + Math.cos(syaw) * robot.ir_range[i], sy + Math.sin(syaw) * robot.ir_range[i]);
      ctx.stroke();
    });
  }
  ctx.fillStyle = colour;
  ctx.globalAlpha = 0.85;
  ctx.beginPath();
  ctx.arc(0, 0, model.body_radius, 0, 2 * Math.PI);
  ctx.fill();
  ctx.globalAlpha = 1;
  ctx.strokeStyle = name === view.selected ? '#000' : '#fff';
  ctx.lineWidth = (name === view.selected ? 2.5 : 1) / scale;
  ctx.stroke();
  ctx.strokeStyle = '#fff';
  ctx.lineWidth = 2.5 / scale;
  ctx.beginPath();
  ctx.moveTo(0, 0);
  ctx.lineTo(model.body_radius, 0);
  ctx.stroke();
  if (robot.leds) {   // the LEDs its controller switched on, in their colours (led8: the body, a disc)
    model.led_positions.forEach(([lx, ly], i) => {
      if (!robot.leds[i]) return;
      const [r, g, b] = model.led_colors[i].map((c) => Math.round(255 * c));
      ctx.fillStyle = `rgb(${r}, ${g}, ${b})`;
      ctx.beginPath();
      ctx.arc(lx, ly, i === 8 ? model.body_radius * 0.45 : Math.max(0.005, 3 / scale), 0, 2 * Math.PI);
      ctx.fill();
    });
  }
  ctx.restore();
  if (name !== view.selected && model.body_radius * scale < NAME_MIN_PX) return;   // a swarm: names would be a blur
  ctx.save();   // the name, upright
  ctx.translate(x, y + model.body_radius * 1.3);
  ctx.scale(1 / scale, -1 / scale);
  ctx.fillStyle = '#222';
  ctx.font = '12px system-ui, sans-serif';
  ctx.textAlign = 'center';
  ctx.fillText(name, 0, 0);
  ctx.restore();
}

window.addEventListener('resize', requestDraw);

// --- choosing a robot --------------------------------------------------------------------------------------

function select(name) {
  if (name === view.selected) return;
  stopDriving();
  view.selected = name;
  $('robot').value = name;
  connect();
  if (view.frame) showFigures();
  requestDraw();
}

$('robot').addEventListener('change', (event) => select(event.target.value));
canvas.addEventListener('click', (event) => {
  canvas.focus();
  if (!view.frame || !view.world) return;
  const t = worldTransform();
  const rect = canvas.getBoundingClientRect();
  const ratio = window.devicePixelRatio || 1;
  const wx = ((event.clientX - rect.left) * ratio - t.cx) / t.scale;
  const wy = -((event.clientY - rect.top) * ratio - t.cy) / t.scale;
  let best = null;
  let bestDistance = 3 * view.world.model.body_radius;
  for (const [name, robot] of Object.entries(view.frame.robots)) {
    if (!robot.pose) continue;
    const distance = Math.hypot(robot.pose[0] - wx, robot.pose[1] - wy);
    if (distance < bestDistance) { best = name; bestDistance = distance; }
  }
  if (best) select(best);
});

// --- actions -----------------------------------------------------------------------------------------------

async function act(name, body = {}) {
  try {
    const response = await fetch(`/api/${name}`, {
      method: 'POST', headers: {'Content-Type': 'application/json'}, body: JSON.stringify(body)});
    const answer = await response.json();
    if (!response.ok) throw new Error(answer.error || response.statusText);
    if (name !== 'drive') showMessage(`${name}: ${answer.message || 'done'}`, false);
    return answer;
  } catch (error) {
    showMessage(`${name}: ${error.message}`, true);
    return null;
  }
}

function showMessage(text, isError) {
  const message = $('message');
  message.textContent = text;
  message.className = isError ? 'error' : 'muted';
}

$('pause').addEventListener('click', () => act('pause', {paused: !(view.frame && view.frame.paused)}));
$('step').addEventListener('click', () => act('step'));
$('reset').addEventListener('click', () => { view.trails = {}; act('reset'); });
$('rtf-form').addEventListener('submit', (event) => {
  event.preventDefault();
  const value = Number($('rtf-input').value);
  if (!Number.isFinite(value) || value < 0) { showMessage('real-time factor: a number >= 0', true); return; }
  act('real_time_factor', {value});
});

// --- driving (teleop_twist_keyboard's keys, held rather than toggled) ----------------------------------------

const KEYS = {
  ArrowUp: [1, 0], w: [1, 0], ArrowDown: [-1, 0], s: [-1, 0],
  ArrowLeft: [0, 1], a: [0, 1], ArrowRight: [0, -1], d: [0, -1],
};

function showSpeeds() {
  setText('speeds', `${view.drive.linear.toFixed(3)} m/s, ${view.drive.angular.toFixed(2)} rad/s`);
}

function command() {
  let forward = 0;
  let turn = 0;
  for (const key of view.drive.keys) { forward += KEYS[key][0]; turn += KEYS[key][1]; }
  forward = Math.sign(forward);
  turn = Math.sign(turn);
  return {linear: forward * view.drive.linear, angular: turn * view.drive.angular};
}

function sendDrive() {
  if (!view.selected) return;
  const {linear, angular} = command();
  view.drive.sent = `${linear},${angular}`;
  setText('command', linear === 0 && angular === 0 ? 'stopped'
    : `${linear.toFixed(3)} m/s, ${angular.toFixed(2)} rad/s → ${view.selected}`);
  act('drive', {robot: view.selected, linear, angular});
}

function driveChanged() {
  sendDrive();
  clearInterval(view.drive.timer);
  view.drive.timer = view.drive.keys.size ? setInterval(sendDrive, DRIVE_REPEAT_MS) : null;
}

function stopDriving() {
  const wasMoving = view.drive.keys.size > 0 || view.drive.sent !== '0,0';
  view.drive.keys.clear();
  if (wasMoving) driveChanged();
}

function keyName(event) { return event.key.length === 1 ? event.key.toLowerCase() : event.key; }
function typing(event) { return event.target instanceof HTMLInputElement || event.target instanceof HTMLSelectElement; }

document.addEventListener('keydown', (event) => {
  if (typing(event) || event.ctrlKey || event.metaKey || event.altKey) return;
  const key = keyName(event);
  if (key in KEYS) {
    event.preventDefault();
    if (!view.drive.keys.has(key)) { view.drive.keys.add(key); driveChanged(); }
  } else if (key === ' ' || key === 'x') {
    event.preventDefault();
    stopDriving();
  } else if (key === 'q' || key === 'z') {
    const factor = key === 'q' ? 1.1 : 1 / 1.1;
    view.drive.linear *= factor;
    view.drive.angular *= factor;
    showSpeeds();
    if (view.drive.keys.size) sendDrive();
  }
});
document.addEventListener('keyup', (event) => {
  const key = keyName(event);
  if (view.drive.keys.delete(key)) driveChanged();
});
window.addEventListener('blur', stopDriving);   // a key released in another window must not keep the robot going
showSpeeds();
connect();
// A hidden tab closes its stream: the view then drops its subscriptions and the simulator pays nothing for it.
document.addEventListener('visibilitychange', () => {
  if (document.hidden) {
    stopDriving();
    events.close();
    setText('connection', 'paused while the tab is hidden');
  } else {
    connect();
  }
});
