// The wire format of the live teleoperation protocol, version 1 (docs/formats.md §3): hand
// frames out (binary, little-endian, 632 bytes), JSON messages in. No DOM, no three.js:
// unit-testable.

export const PROTOCOL_VERSION = 1;
export const CLIENT_NAME = 'mimicrete-page/1';
export const JOINTS = 25; // WebXR hand joints, XRHand iteration order
export const FLOATS_PER_HAND = JOINTS * 3;
export const FRAME_BYTES = 32 + 2 * FLOATS_PER_HAND * 4; // 632
export const FLAG_RIGHT = 1;
export const FLAG_LEFT = 2;
const MAGIC = [0x4d, 0x48, 0x46, 0x31]; // "MHF1"
const RIGHT_OFFSET = 32;
const LEFT_OFFSET = RIGHT_OFFSET + FLOATS_PER_HAND * 4; // 332

/**
 * A reusable 632-byte frame. `pack` overwrites it; WebSocket.send copies the bytes, so one buffer
 * serves every frame without allocating.
 */
export class HandFramePacker {
  constructor() {
    this.buffer = new ArrayBuffer(FRAME_BYTES);
    this.view = new DataView(this.buffer);
    this.bytes = new Uint8Array(this.buffer);
    this.bytes.set(MAGIC, 0);
  }

  /**
   * @param {number} seq      u32 frame counter
   * @param {number} t        XR frame time, seconds
   * @param {number} sentMs   performance.now() at send, echoed back by the server
   * @param {Float32Array|null} right 75 floats (25 × xyz, metres, `local` space) or null if untracked
   * @param {Float32Array|null} left  same for the left hand
   * @returns {ArrayBuffer} the packed frame (this.buffer)
   */
  pack(seq, t, sentMs, right, left) {
    const v = this.view;
    v.setUint32(4, seq >>> 0, true);
    v.setFloat64(8, t, true);
    v.setFloat64(16, sentMs, true);
    v.setUint32(24, (right ? FLAG_RIGHT : 0) | (left ? FLAG_LEFT : 0), true);
    v.setUint32(28, 0, true);
    writeHand(v, RIGHT_OFFSET, right);
    writeHand(v, LEFT_OFFSET, left);
    return this.buffer;
  }
}

function writeHand(view, offset, joints) {
  for (let i = 0; i < FLOATS_PER_HAND; i++) {
    // An untracked hand's floats are ignored by the server; zeros keep frames reproducible.
    view.setFloat32(offset + 4 * i, joints ? joints[i] : 0, true);
  }
}

/** Unpack a frame (the inverse of pack; used by the page's self-test and by tests). */
export function unpackHandFrame(buffer) {
  const v = new DataView(buffer);
  if (buffer.byteLength !== FRAME_BYTES) throw new Error(`frame of ${buffer.byteLength} bytes`);
  for (let i = 0; i < 4; i++) if (v.getUint8(i) !== MAGIC[i]) throw new Error('bad magic');
  const flags = v.getUint32(24, true);
  const hand = (offset, bit) => {
    if (!(flags & bit)) return null;
    const out = new Float32Array(FLOATS_PER_HAND);
    for (let i = 0; i < FLOATS_PER_HAND; i++) out[i] = v.getFloat32(offset + 4 * i, true);
    return out;
  };
  return {
    seq: v.getUint32(4, true),
    t: v.getFloat64(8, true),
    sentMs: v.getFloat64(16, true),
    flags,
    right: hand(RIGHT_OFFSET, FLAG_RIGHT),
    left: hand(LEFT_OFFSET, FLAG_LEFT),
  };
}

export function helloMessage(role = 'driver') {
  return JSON.stringify({ type: 'hello', protocol: PROTOCOL_VERSION, role, client: CLIENT_NAME });
}

/** The driver's control actions (docs/formats.md §3); engage / release work the clutch. */
export const CONTROL_ACTIONS = ['start', 'stop', 'discard', 'engage', 'release', 'recentre'];

export function controlMessage(action) {
  if (!CONTROL_ACTIONS.includes(action)) {
    throw new Error(`unknown control action ${action}`);
  }
  return JSON.stringify({ type: 'control', action });
}

export const GESTURE_ACTIONS = ['enter', 'exit', 'record', 'pause', 'train', 'status'];

/**
 * A gesture-mode request: enter (optionally with perClass samples per class), exit, record (a
 * class, default the next one that is not full; recording a class again redoes it), pause, train.
 */
export function gesturesMessage(action, { cls = null, perClass = null } = {}) {
  if (!GESTURE_ACTIONS.includes(action)) throw new Error(`unknown gestures action ${action}`);
  const msg = { type: 'gestures', action };
  if (cls !== null) msg.class = cls;
  if (perClass !== null) msg.per_class = perClass;
  return JSON.stringify(msg);
}

/**
 * The driver's acknowledgement of the states it received: [[seq, performance.now() at receipt],
 * ...]. The server records, per control step, how stale the hand was (docs/formats.md §3).
 */
export function ackMessage(states) {
  return JSON.stringify({ type: 'ack', states });
}

const KNOWN_TYPES = new Set(['hello', 'state', 'scene', 'calibration', 'episode', 'error', 'gestures']);

/**
 * Parse one text message from the server. Returns the object, or null (with a console warning)
 * for anything that is not a JSON object with a known `type`: the page never throws on input.
 */
export function parseServerMessage(text) {
  let msg;
  try {
    msg = JSON.parse(text);
  } catch (e) {
    console.warn('mimicrete: unparsable server message', e);
    return null;
  }
  if (msg === null || typeof msg !== 'object' || !KNOWN_TYPES.has(msg.type)) {
    console.warn('mimicrete: unknown server message', msg);
    return null;
  }
  if (msg.type === 'hello' && msg.protocol !== PROTOCOL_VERSION) {
    console.warn(`mimicrete: server speaks protocol ${msg.protocol}, page ${PROTOCOL_VERSION}`);
  }
  return msg;
}

/** ws:// or wss:// URL of /ws on the page's own origin, passing the page's token on. */
export function socketUrl(location) {
  const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const token = new URLSearchParams(location.search).get('token');
  const query = token ? `?token=${encodeURIComponent(token)}` : '';
  return `${scheme}//${location.host}/ws${query}`;
}
