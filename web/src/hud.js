// Heads-up display: the same lines in a DOM panel (visible in screenshots even while an XR session
// owns the canvas) and on a CanvasTexture plane that follows the headset.
import * as THREE from 'three';
import { gesturePrompt, gestureResult } from './gestures.js';

const fmt = (x, digits = 1) => (Number.isFinite(x) ? x.toFixed(digits) : '–');

/** The HUD lines of the gesture mode (the desktop page shows its panel instead). */
export const GESTURE_LINES = new Set(['teach', 'samples', 'trained']);

/** The HUD's lines, as [label, value, css class] from the page's view of the session. */
export function hudLines(v) {
  const s = v.state ?? {};
  const dropped = s.dropped ?? {};
  const droppedServer = Object.values(dropped).reduce((a, b) => a + (Number(b) || 0), 0);
  const droppedText = Object.entries(dropped).filter(([, n]) => n > 0)
    .map(([k, n]) => `${k} ${n}`).join(', ');
  const gesture = s.gesture
    ? `${s.gesture}${Number.isFinite(s.margin) ? ` (margin ${fmt(s.margin, 2)})` : ''}`
    : '–';
  let follow = '–';
  if (v.state) follow = s.following ? 'following' : `not following: ${s.why ?? '?'}`;
  // what to do about it (the server's hint for the reason)
  if (v.state && s.hint && s.why) follow += ` · ${s.hint}`;
  const rec = s.recording ? `REC step ${s.step ?? 0}` : 'idle';
  const g = v.gestures;
  const mode = g?.active
    ? [
      ['teach', gesturePrompt(g), g.current ? 'rec' : g.error ? 'warn' : ''],
      ['samples', g.classes.map((c) => `${c} ${g.counts[c] ?? 0}/${g.target}`).join(' · '), ''],
      ['trained', g.report ? gestureResult(g.report) : '–', g.report ? 'ok' : ''],
    ]
    : [
      ['episode', `${s.episode ?? '–'} · ${rec}`, s.recording ? 'rec' : ''],
      ['last result', s.last_result ?? v.lastEvent ?? '–', ''],
    ];
  return [
    ['link', `${v.connection}${v.role ? ` · ${v.role}` : ''}${v.task ? ` · ${v.task}` : ''}`,
      v.connection === 'connected' ? 'ok' : 'warn'],
    ['gesture', gesture, ''],
    ['model', modelText(v.gestureModel), v.gestureModel?.source === 'user' ? 'ok' : ''],
    ['robot', follow, s.following ? 'ok' : 'warn'],
    ...mode,
    ['hands', `${fmt(v.handFps, 0)} fps sent · ${fmt(s.fps, 0)} fps at server · ${v.tracked}`, ''],
    ['round trip', `${fmt(v.rttP50)} ms p50 · ${fmt(v.rttLast)} ms last`, ''],
    ['dropped', `${droppedServer} at server${droppedText ? ` (${droppedText})` : ''} · ${v.skipped} not sent`,
      droppedServer + v.skipped > 0 ? 'warn' : ''],
    ...(v.error ? [['error', v.error, 'warn']] : []),
  ];
}

/** Which gesture model reads the hand, and how well it did on its held-out samples. */
export function modelText(m) {
  if (!m) return '–';
  const acc = Number.isFinite(m.test_accuracy) ? ` · ${(100 * m.test_accuracy).toFixed(1)} % held-out` : '';
  const name = { user: 'yours', shipped: 'shipped (synthetic hands)' }[m.source]
    ?? (m.file ? m.file.split('/').pop() : m.source);
  return `${name}${acc}`;
}

export class DomHud {
  constructor(element) {
    this.element = element;
    this.last = '';
  }

  update(lines) {
    const key = JSON.stringify(lines);
    if (key === this.last) return;
    this.last = key;
    this.element.replaceChildren(...lines.map(([label, value, cls]) => {
      const row = document.createElement('div');
      row.className = `row ${cls}`;
      row.dataset.field = label.replace(' ', '_');
      const l = document.createElement('span');
      l.className = 'label';
      l.textContent = label;
      const val = document.createElement('span');
      val.className = 'value';
      val.textContent = value;
      row.append(l, val);
      return row;
    }));
  }
}

/** A 0.36 m × 0.24 m panel low on the left, 0.6 m away, turned to the eyes (child of the camera),
 * so the workspace straight ahead stays clear. */
export class HeadsetHud {
  constructor(camera) {
    this.canvas = document.createElement('canvas');
    this.canvas.width = 720;
    this.canvas.height = 480;
    this.ctx = this.canvas.getContext('2d');
    this.texture = new THREE.CanvasTexture(this.canvas);
    this.texture.colorSpace = THREE.SRGBColorSpace;
    const material = new THREE.MeshBasicMaterial({ map: this.texture, transparent: true, depthTest: false });
    this.mesh = new THREE.Mesh(new THREE.PlaneGeometry(0.36, 0.24), material);
    this.mesh.position.set(-0.24, -0.2, -0.55);
    this.mesh.rotation.set(-0.3, 0.4, 0, 'YXZ');
    this.mesh.renderOrder = 10;
    this.mesh.visible = false; // only inside an XR session; the DOM HUD serves the desktop
    camera.add(this.mesh);
    this.last = '';
  }

  update(lines) {
    const key = JSON.stringify(lines);
    if (key === this.last) return;
    this.last = key;
    const { ctx, canvas } = this;
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.fillStyle = 'rgba(10, 14, 20, 0.78)';
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.font = '26px "DejaVu Sans", sans-serif';
    ctx.textBaseline = 'top';
    lines.forEach(([label, value, cls], i) => {
      const y = 14 + i * 42;
      ctx.fillStyle = '#8fa3b8';
      ctx.fillText(label, 16, y);
      ctx.fillStyle = cls === 'warn' ? '#ffb347' : cls === 'rec' ? '#ff5c5c' : cls === 'ok' ? '#7dde92' : '#e8eef4';
      ctx.fillText(value, 190, y, canvas.width - 200);
    });
    this.texture.needsUpdate = true;
  }
}
