// The teleoperation page: an XR session reads both hands every frame and sends them to the
// mimicrete server over one WebSocket; the server's states pose the robot and fill the HUD.
import * as THREE from 'three';
import {
  CONTROL_ACTIONS, HandFramePacker, ackMessage, controlMessage, gesturesMessage, helloMessage, parseServerMessage,
  socketUrl, unpackHandFrame,
} from './protocol.js';
import { RobotScene } from './scene.js';
import { HandReader, HandSpheres, JOINT_NAMES } from './hands.js';
import { DomHud, GESTURE_LINES, HeadsetHud, hudLines } from './hud.js';
import { Spectator, frameWorkspace } from './spectator.js';
import { GesturePanel } from './gestures.js';

const params = new URLSearchParams(location.search);
const emulateKind = ['quest3', 'quest2'].includes(params.get('emulate')) ? params.get('emulate') : null;
// ?spectator=1 (or =full): while an XR session runs, the page shows a third-person view of the
// scene (robot, tile, target, the user's head and hands) over the whole window; =pip: in a corner.
// ?spectator_hz=N caps its frame rate (default 20).
const spectatorMode = { 1: 'full', full: 'full', pip: 'pip' }[params.get('spectator')] ?? null;
const spectatorHz = Number(params.get('spectator_hz') ?? 20);
const MAX_BUFFERED_BYTES = 64 * 1024; // skip a frame rather than queue behind a slow link
const MAX_SAMPLES = 200000;

// ---------------------------------------------------------------- test hook (Playwright) ----
const hook = {
  emulate: emulateKind,
  device: null, // the IWER XRDevice when emulating
  hello: null,
  state: null, // the last state message
  counts: { framesSent: 0, statesReceived: 0, skipped: 0, messages: 0, untracked: 0, acksSent: 0 },
  rtt: [], // round-trip samples, ms (state received − echoed sent_ms)
  replaySamples: [], // [seq, playback ms, record index | null] per frame sent during a replay
  events: [], // episode / calibration / error messages, gestures messages but progress
  gestures: null, // the last gestures message (the gesture mode's state)
  gestureMessages: 0,
  sendGestures: (action, opts) => sendGestures(action, opts),
  headsetLines: () => hudLines(view), // what the headset's HUD panel shows
  inSession: false,
  ready: false,
  enterVR: () => enterVR(),
  exitVR: () => session?.end(),
  refSpace: () => renderer.xr.getReferenceSpace(),
  replay: null, // set when emulating: (recording, mode) => Promise<void>
  replayDone: () => (replay ? replay.done : true),
  scene: () => robot.describe(), // what is drawn (end effector parts, view_from_base, frames)
  spectator: () => (spectator ? { mode: spectatorMode, frames: spectator.frames } : null),
  // The page's own packer, exposed so tests can compare it with an independent decoder.
  pack: (seq, t, sentMs, right, left) => Array.from(new Uint8Array(new HandFramePacker().pack(
    seq, t, sentMs, right && Float32Array.from(right), left && Float32Array.from(left)))),
  unpack: (bytes) => unpackHandFrame(Uint8Array.from(bytes).buffer),
  jointNames: JOINT_NAMES, // the joints the page reads, in wire order (a test checks ur3-kin's table)
};
window.__mimicrete = hook;

let emu = null; // the emulate.js module
let replay = null;
if (emulateKind) {
  // Dynamic import: iwer + devui live in their own chunks, fetched only under emulation.
  emu = await import('./emulate.js');
  // ?devui=0 leaves out IWER's dev UI (mouse/keyboard hand controls), for automated runs.
  hook.device = emu.installEmulator(emulateKind, { devui: params.get('devui') !== '0' });
  hook.replay = async (recording, mode = 'exact') => {
    if (!session) throw new Error('enter VR before replaying');
    replay?.stop();
    replay = new emu.Replay(hook.device, renderer.xr.getReferenceSpace(), recording, mode);
    hook.replaySamples.length = 0;
    replay.start();
  };
}

// ---------------------------------------------------------------- three.js ----
const renderer = new THREE.WebGLRenderer({ antialias: true, canvas: document.getElementById('view') });
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
renderer.setSize(window.innerWidth, window.innerHeight);
renderer.xr.enabled = true;
// Hands and view_from_base are both in the `local` space (origin at the head when the session began).
renderer.xr.setReferenceSpaceType('local');

const scene = new THREE.Scene();
scene.background = new THREE.Color(0x20262e);
scene.add(new THREE.HemisphereLight(0xdde8ff, 0x303030, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(0.5, 2, 1);
scene.add(sun);
const floor = new THREE.GridHelper(4, 40, 0x556070, 0x39414c);
floor.position.y = -1.6; // roughly the floor under a standing user's head
scene.add(floor);

// Desktop view (no session): the third-person view of the workspace (set again at each hello).
// In a session three.js poses this camera as the headset.
const camera = new THREE.PerspectiveCamera(60, window.innerWidth / window.innerHeight, 0.01, 50);
camera.position.set(0.8, 0.3, 0.6);
camera.lookAt(0, -0.6, -0.5);
scene.add(camera); // so the headset HUD (a child of the camera) is drawn

const robot = new RobotScene(scene);
const readers = { right: new HandReader(), left: new HandReader() };
const spheres = { right: new HandSpheres(scene, 0x6fb7ff), left: new HandSpheres(scene, 0xffa86f) };
const domHud = new DomHud(document.getElementById('hud'));
const headsetHud = new HeadsetHud(camera);
const spectator = spectatorMode
  ? new Spectator(document.getElementById('spectator'), scene, spectatorMode, spectatorHz)
  : null;

addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
  spectator?.resize();
});

// ---------------------------------------------------------------- WebSocket ----
const view = {
  connection: 'connecting', role: null, task: null, state: null, lastEvent: null, error: null,
  handFps: NaN, rttP50: NaN, rttLast: NaN, skipped: 0, tracked: 'no hands',
  gestures: null, gestureModel: null,
};
let socket = null;
let retryMs = 500;

function connect() {
  view.connection = 'connecting';
  socket = new WebSocket(socketUrl(location));
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => {
    view.connection = 'connected';
    retryMs = 500;
    socket.send(helloMessage('driver'));
  };
  socket.onmessage = (ev) => {
    if (typeof ev.data !== 'string') return; // the server sends text only
    hook.counts.messages++;
    const msg = parseServerMessage(ev.data);
    if (msg) onMessage(msg);
  };
  socket.onclose = () => {
    view.connection = 'disconnected';
    view.role = null;
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 5000);
  };
}

const recentRtt = [];
function onMessage(msg) {
  switch (msg.type) {
    case 'hello':
      hook.hello = msg;
      view.role = msg.role;
      view.task = msg.task;
      view.gestureModel = msg.gesture_model ?? null;
      clutchButton.hidden = msg.mapping === 'absolute'; // no clutch: the hand's pose is the target
      robot.build(msg.scene, msg.view_from_base);
      if (msg.frames) robot.update({ frames: msg.frames });
      reframe();
      if (msg.gestures) onMessage(msg.gestures); // the gesture mode's state (a gestures message)
      break;
    case 'gestures':
      hook.gestures = msg;
      hook.gestureMessages++;
      if (msg.event !== 'progress') hook.events.push(msg);
      view.gestures = msg;
      view.gestureModel = msg.model ?? view.gestureModel;
      gesturePanel.update(msg);
      gesturesButton.textContent = msg.active ? 'Leave gestures' : 'Gestures';
      gesturesButton.classList.toggle('active', msg.active);
      if (msg.event === 'trained') view.lastEvent = 'gesture model trained';
      break;
    case 'state': {
      hook.state = msg;
      hook.counts.statesReceived++;
      view.state = msg;
      robot.update(msg);
      clutchButton.textContent = msg.engaged ? 'Release' : 'Engage';
      if (Number.isInteger(msg.seq) && view.role === 'driver') ack(msg.seq);
      if (Number.isFinite(msg.sent_ms)) {
        const rtt = performance.now() - msg.sent_ms;
        if (hook.rtt.length < MAX_SAMPLES) hook.rtt.push(rtt);
        recentRtt.push(rtt);
        if (recentRtt.length > 90) recentRtt.shift();
        view.rttLast = rtt;
      }
      break;
    }
    case 'scene': // a new episode whose scene differs (the screw task's plate and bolt move)
      hook.events.push({ type: 'scene', entities: msg.scene?.length ?? 0 });
      robot.build(msg.scene, null); // the view stays
      if (hook.state) robot.update(hook.state);
      reframe();
      break;
    case 'calibration':
      robot.setView(msg.view_from_base);
      reframe();
      hook.events.push(msg);
      view.lastEvent = 'recentred';
      break;
    case 'episode':
      hook.events.push(msg);
      view.lastEvent = `episode ${msg.index} ${msg.event}${msg.result ? `: ${msg.result}` : ''}`;
      break;
    case 'error':
      hook.events.push(msg);
      view.error = msg.message;
      break;
  }
}

/** Aim the desktop camera and the spectator at the workspace the server described. */
function reframe() {
  if (!session) {
    frameWorkspace(camera, robot);
  }
  spectator?.frame(robot);
}

function control(action) {
  if (socket?.readyState === WebSocket.OPEN) socket.send(controlMessage(action));
}
for (const action of CONTROL_ACTIONS.filter((a) => a !== 'engage' && a !== 'release')) {
  document.getElementById(`btn-${action}`).addEventListener('click', () => control(action));
}
// one button works the clutch: Release while it is engaged, Engage while released
const clutchButton = document.getElementById('btn-clutch');
clutchButton.addEventListener('click', () => control(view.state?.engaged ? 'release' : 'engage'));

// The gesture mode: teach the SVM your own gestures (the server records, trains and reports).
function sendGestures(action, opts) {
  if (socket?.readyState === WebSocket.OPEN) socket.send(gesturesMessage(action, opts));
}
const gesturePanel = new GesturePanel(document.getElementById('gestures'), sendGestures);
const gesturesButton = document.getElementById('btn-gestures');
gesturesButton.addEventListener('click', () => sendGestures(view.gestures?.active ? 'exit' : 'enter'));

// ---------------------------------------------------------------- XR session ----
let session = null;
const enterButton = document.getElementById('btn-vr');

async function enterVR() {
  if (session) return;
  if (!navigator.xr) throw new Error('WebXR is not available (needs https or localhost)');
  // hand-tracking is optional so that a headset without it still shows the robot; the `local`
  // reference space is always available to immersive sessions.
  const s = await navigator.xr.requestSession('immersive-vr', {
    requiredFeatures: ['local'],
    optionalFeatures: ['hand-tracking'],
  });
  s.addEventListener('end', () => {
    session = null;
    hook.inSession = false;
    headsetHud.mesh.visible = false;
    spectator?.show(false);
    frameWorkspace(camera, robot);
    enterButton.textContent = 'Enter VR';
    replay?.stop();
    replay = null;
  });
  await renderer.xr.setSession(s);
  session = s;
  hook.inSession = true;
  headsetHud.mesh.visible = true;
  spectator?.show(true);
  enterButton.textContent = 'Exit VR';
}

enterButton.addEventListener('click', () => {
  if (session) session.end();
  else enterVR().catch((e) => { view.error = String(e.message ?? e); });
});

async function checkXR() {
  const ok = navigator.xr && (await navigator.xr.isSessionSupported('immersive-vr').catch(() => false));
  enterButton.disabled = !ok;
  if (!ok) enterButton.textContent = 'VR not available';
}

// ---------------------------------------------------------------- frame loop ----
const packer = new HandFramePacker();
let seq = 0;
let lastMs = performance.now();
let fpsCount = 0;
let fpsSince = performance.now();
let hudSince = 0;

function readHands(frame) {
  const ref = renderer.xr.getReferenceSpace();
  const out = { right: null, left: null };
  for (const source of frame.session.inputSources) {
    const side = source.handedness;
    if (!source.hand || (side !== 'right' && side !== 'left')) continue;
    const reader = readers[side];
    if (reader.read(frame, source.hand, ref)) out[side] = reader;
  }
  return out;
}

// States received, acknowledged in batches (every ACK_BATCH states or ACK_MS).
const ACK_BATCH = 16;
const ACK_MS = 250;
let acks = [];
let ackSince = 0;

function ack(stateSeq) {
  const now = performance.now();
  acks.push([stateSeq, now]);
  if (acks.length >= ACK_BATCH || now - ackSince >= ACK_MS) {
    if (socket?.readyState === WebSocket.OPEN) socket.send(ackMessage(acks));
    hook.counts.acksSent++;
    acks = [];
    ackSince = now;
  }
}

function sendFrame(time, hands) {
  if (socket?.readyState !== WebSocket.OPEN || view.role !== 'driver') return;
  if (socket.bufferedAmount > MAX_BUFFERED_BYTES) {
    view.skipped = ++hook.counts.skipped;
    return;
  }
  const s = seq;
  seq = (seq + 1) >>> 0;
  // t: the XR frame's time (rAF argument, ms) in seconds; sent_ms is echoed for the round trip.
  socket.send(packer.pack(s, time / 1000, performance.now(),
    hands.right?.positions ?? null, hands.left?.positions ?? null));
  hook.counts.framesSent++;
  fpsCount++;
  if (replay && hook.replaySamples.length < MAX_SAMPLES) {
    const r = replay.sample();
    hook.replaySamples.push([s, r.timeMs, r.index]);
  }
}

renderer.setAnimationLoop((time, frame) => {
  const now = performance.now();
  const dt = Math.min((now - lastMs) / 1000, 0.1);
  lastMs = now;
  if (frame) {
    const hands = readHands(frame);
    spheres.right.update(hands.right?.positions, hands.right?.radii);
    spheres.left.update(hands.left?.positions, hands.left?.radii);
    const n = (hands.right ? 1 : 0) + (hands.left ? 1 : 0);
    if (n === 0) hook.counts.untracked++;
    view.tracked = n === 2 ? 'both hands' : hands.right ? 'right hand' : hands.left ? 'left hand' : 'no hands';
    sendFrame(time, hands);
  } else {
    spheres.right.update(null);
    spheres.left.update(null);
  }
  if (now - fpsSince >= 1000) {
    view.handFps = (fpsCount * 1000) / (now - fpsSince);
    fpsCount = 0;
    fpsSince = now;
  }
  robot.tick(dt);
  if (now - hudSince > 100) { // the HUD redraws at most 10 times a second
    hudSince = now;
    view.rttP50 = median(recentRtt);
    const lines = hudLines(view);
    // on the desktop the gesture panel shows the gesture mode; the headset has only the HUD
    domHud.update(view.gestures?.active ? lines.filter(([l]) => !GESTURE_LINES.has(l)) : lines);
    headsetHud.update(lines);
  }
  renderer.render(scene, camera);
  // In a session `camera` now holds the headset's pose: the spectator draws it as a head.
  if (session && spectator) spectator.render(camera, [headsetHud.mesh]);
});

function median(xs) {
  if (xs.length === 0) return NaN;
  const s = [...xs].sort((a, b) => a - b);
  return s[s.length >> 1];
}

await checkXR();
connect();
hook.ready = true;
