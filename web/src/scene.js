// The robot cell the server describes: Foxglove-style SceneEntity primitives, each attached to a
// named frame posed every state by `frames` (poses in the robot's Base frame, Z up, metres), all
// under one group whose matrix is `view_from_base` (Base → XR `local`, column-major).
import * as THREE from 'three';

const SUCTION_PREFIX = 'suction'; // entities lit when {"kind":"suction","on":true}
const SCREW_PREFIX = 'screw'; // entities spun about their local Z while the screwdriver runs
const SPIN_RAD_PER_S = 4 * Math.PI;

function poseOf(p) {
  const pos = p?.position ?? {};
  const q = p?.orientation ?? {};
  return {
    position: new THREE.Vector3(pos.x ?? 0, pos.y ?? 0, pos.z ?? 0),
    quaternion: new THREE.Quaternion(q.x ?? 0, q.y ?? 0, q.z ?? 0, q.w ?? 1),
  };
}

function material(c) {
  const a = c?.a ?? 1;
  return new THREE.MeshStandardMaterial({
    color: new THREE.Color(c?.r ?? 0.7, c?.g ?? 0.7, c?.b ?? 0.7),
    transparent: a < 1,
    opacity: a,
    roughness: 0.55,
    metalness: 0.1,
  });
}

function place(mesh, prim) {
  const { position, quaternion } = poseOf(prim.pose);
  mesh.position.copy(position);
  mesh.quaternion.copy(quaternion);
}

const unitBox = new THREE.BoxGeometry(1, 1, 1);
const unitSphere = new THREE.SphereGeometry(0.5, 24, 16);

function cylinderGeometry(bottom, top) {
  // three.js cylinders run along +Y; Foxglove's along +Z: turn +Y onto +Z. Diameter 1, height 1.
  const g = new THREE.CylinderGeometry(0.5 * top, 0.5 * bottom, 1, 32);
  g.rotateX(Math.PI / 2);
  return g;
}

/** Build the meshes of one SceneEntity into a group (in its frame's coordinates). */
export function entityGroup(entity) {
  const group = new THREE.Group();
  group.name = entity.id ?? '';
  for (const c of entity.cubes ?? []) {
    const m = new THREE.Mesh(unitBox, material(c.color));
    place(m, c);
    m.scale.set(c.size?.x ?? 0.1, c.size?.y ?? 0.1, c.size?.z ?? 0.1);
    group.add(m);
  }
  for (const c of entity.cylinders ?? []) {
    const m = new THREE.Mesh(cylinderGeometry(c.bottom_scale ?? 1, c.top_scale ?? 1), material(c.color));
    place(m, c);
    m.scale.set(c.size?.x ?? 0.1, c.size?.y ?? 0.1, c.size?.z ?? 0.1);
    group.add(m);
  }
  for (const s of entity.spheres ?? []) {
    const m = new THREE.Mesh(unitSphere, material(s.color));
    place(m, s);
    m.scale.set(s.size?.x ?? 0.1, s.size?.y ?? 0.1, s.size?.z ?? 0.1);
    group.add(m);
  }
  return group;
}

export class RobotScene {
  constructor(scene) {
    this.root = new THREE.Group(); // Base frame expressed in `local`
    this.root.name = 'view_from_base';
    this.root.matrixAutoUpdate = false;
    scene.add(this.root);
    this.frames = new Map(); // frame_id → Object3D under root ('base' is root itself)
    this.suction = []; // materials to light
    this.screws = []; // groups to spin
    this.spin = 0;
    this.target = new THREE.Mesh(
      new THREE.SphereGeometry(0.012, 16, 12),
      new THREE.MeshBasicMaterial({ color: 0xffcc00, transparent: true, opacity: 0.7 }),
    );
    this.target.visible = false;
    this.root.add(this.target);
  }

  /** Replace the scene with the hello's entities. */
  build(entities, viewFromBase) {
    for (const f of this.frames.values()) this.root.remove(f);
    this.frames.clear();
    this.suction = [];
    this.screws = [];
    this.setView(viewFromBase);
    for (const entity of entities ?? []) {
      const group = entityGroup(entity);
      this.frame(entity.frame_id ?? 'base').add(group);
      const id = (entity.id ?? '').toLowerCase();
      if (id.startsWith(SUCTION_PREFIX)) {
        group.traverse((o) => o.material && this.suction.push(o.material));
      }
      if (id.startsWith(SCREW_PREFIX)) this.screws.push(group);
    }
  }

  frame(id) {
    if (id === 'base') return this.root;
    let f = this.frames.get(id);
    if (!f) {
      f = new THREE.Group();
      f.name = id;
      this.root.add(f);
      this.frames.set(id, f);
    }
    return f;
  }

  setView(viewFromBase) {
    if (Array.isArray(viewFromBase) && viewFromBase.length === 16) {
      this.root.matrix.fromArray(viewFromBase); // column-major, as the server sends it
      this.root.matrixWorldNeedsUpdate = true;
    }
  }

  /** Apply one state: frame poses ([x,y,z,qx,qy,qz,qw] in Base), end effector, target. */
  update(state) {
    for (const [id, p] of Object.entries(state.frames ?? {})) {
      if (!Array.isArray(p) || p.length !== 7) continue;
      const f = this.frame(id);
      f.position.set(p[0], p[1], p[2]);
      f.quaternion.set(p[3], p[4], p[5], p[6]);
    }
    const ee = state.ee ?? {};
    const lit = ee.kind === 'suction' && ee.on;
    for (const m of this.suction) {
      m.emissive.setRGB(lit ? 0.1 : 0, lit ? 0.9 : 0, lit ? 0.3 : 0);
    }
    this.spin = ee.kind === 'screw' && ee.on ? Math.sign(ee.spin ?? 0) : 0;
    const t = state.target;
    this.target.visible = Array.isArray(t) && t.length >= 3;
    if (this.target.visible) this.target.position.set(t[0], t[1], t[2]);
  }

  /** Per render frame: animate what moves between states (the screw's spin). */
  tick(dt) {
    if (this.spin === 0) return;
    for (const g of this.screws) g.rotateZ(this.spin * SPIN_RAD_PER_S * dt);
  }
}
