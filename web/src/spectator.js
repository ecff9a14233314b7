// A third-person view of the teleoperation scene: the robot cell, the user's tracked hands and a
// marker for the user's head, seen from behind the user's right shoulder. In a headset session
// the page's canvas belongs to the headset (or, emulated, to IWER), so the spectator draws into
// a canvas of its own with a second renderer sharing the same scene.
import * as THREE from 'three';

// From the workspace towards the camera, in `local`: behind the user's left shoulder and above, so
// the head shows on the right (the page's HUD covers the top left).
const VIEW_DIRECTION = new THREE.Vector3(-0.75, 0.8, 0.9).normalize();
const MARGIN_M = 0.1; // around each point that must be in view (the head's radius)

/** Points that must be in view, in `local`: the head (origin), the robot's base, tool and object
 * (frames `tool0` and `tile` of the robot scene, mapped by view_from_base) and the centre of the
 * scene's `target` entity (where the object goes; the screw task has none, its bolt is under the
 * nut). */
function workspacePoints(robot) {
  robot.root.updateMatrixWorld(true);
  const points = [new THREE.Vector3(0, 0, 0)];
  const m = robot.root.matrix;
  points.push(new THREE.Vector3(0, 0, 0).applyMatrix4(m));
  for (const id of ['tool0', 'tile']) {
    const f = robot.frames.get(id);
    if (f) points.push(f.position.clone().applyMatrix4(m));
  }
  const target = robot.entities.get('target');
  if (target) points.push(new THREE.Box3().setFromObject(target).getCenter(new THREE.Vector3()));
  return points;
}

/** Aim `camera` (a PerspectiveCamera) along `direction` at the workspace: the closest distance
 * at which the head and the workspace points, padded by MARGIN_M, are all inside the view. */
export function frameWorkspace(camera, robot, direction = VIEW_DIRECTION) {
  const points = workspacePoints(robot);
  const centre = new THREE.Vector3();
  for (const p of points) centre.add(p);
  centre.divideScalar(points.length);
  const back = direction.clone().normalize(); // from the centre towards the camera
  const right = new THREE.Vector3(0, 1, 0).cross(back).normalize();
  const up = back.clone().cross(right);
  const tanV = Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2);
  const tanH = tanV * camera.aspect;
  let distance = 0.3;
  const v = new THREE.Vector3();
  for (const p of points) {
    v.subVectors(p, centre);
    const toward = v.dot(back);
    const x = Math.abs(v.dot(right)) + MARGIN_M;
    const y = Math.abs(v.dot(up)) + MARGIN_M;
    distance = Math.max(distance, toward + x / tanH, toward + y / tanV);
  }
  camera.position.copy(centre).addScaledVector(back, distance);
  camera.lookAt(centre);
  camera.updateMatrixWorld(true);
}

/** The user's head: a translucent sphere with a visor facing the view direction (−Z). */
function headMarker() {
  const g = new THREE.Group();
  g.name = 'spectator-head';
  const skull = new THREE.Mesh(
    new THREE.SphereGeometry(0.09, 24, 16),
    new THREE.MeshStandardMaterial({ color: 0xb8c4d0, transparent: true, opacity: 0.55 }),
  );
  const visor = new THREE.Mesh(
    new THREE.BoxGeometry(0.17, 0.08, 0.07),
    new THREE.MeshStandardMaterial({ color: 0x1d232b }),
  );
  visor.position.set(0, 0.005, -0.085);
  g.add(skull, visor);
  g.visible = false;
  return g;
}

export class Spectator {
  /**
   * @param {HTMLCanvasElement} canvas its own canvas (shown only while a session runs)
   * @param {THREE.Scene} scene the page's scene
   * @param {'full'|'pip'} mode the whole window, or a picture-in-picture corner
   * @param {number} maxHz the most frames a second it draws (0: every frame)
   */
  constructor(canvas, scene, mode = 'full', maxHz = 20) {
    this.canvas = canvas;
    this.minIntervalMs = maxHz > 0 ? 1000 / maxHz : 0;
    this.lastMs = -Infinity;
    this.scene = scene;
    this.mode = mode;
    canvas.classList.add(`spectator-${mode}`);
    this.renderer = new THREE.WebGLRenderer({ antialias: true, canvas });
    this.renderer.setPixelRatio(1);
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.01, 50);
    this.head = headMarker();
    scene.add(this.head);
    this.frames = 0;
    this.resize();
  }

  resize() {
    const w = this.mode === 'pip' ? Math.round(window.innerWidth * 0.4) : window.innerWidth;
    const h = this.mode === 'pip' ? Math.round(window.innerHeight * 0.4) : window.innerHeight;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  frame(robot) {
    frameWorkspace(this.camera, robot);
  }

  show(on) {
    this.canvas.style.display = on ? 'block' : 'none';
  }

  /** Draw the scene from the spectator's camera, `headCamera`'s pose drawn as the head and
   * `hide` (e.g. the headset HUD) left out. */
  render(headCamera, hide = []) {
    // A second full view costs as much as the headset's: at most maxHz, so the hand stream
    // keeps its rate on slow (software-rendered) machines.
    const now = performance.now();
    if (now - this.lastMs < this.minIntervalMs) return;
    this.lastMs = now;
    this.head.position.setFromMatrixPosition(headCamera.matrixWorld);
    this.head.quaternion.setFromRotationMatrix(headCamera.matrixWorld);
    this.head.visible = true;
    const shown = hide.map((o) => o.visible);
    for (const o of hide) o.visible = false;
    this.renderer.render(this.scene, this.camera);
    hide.forEach((o, i) => { o.visible = shown[i]; });
    this.head.visible = false;
    this.frames++;
  }
}
