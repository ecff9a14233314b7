// The robot cell the server describes: Foxglove-style SceneEntity primitives, each attached to a
// named frame posed every state by `frames` (poses in the robot's Base frame, Z up, metres), all
// under one group whose matrix is `view_from_base` (Base → XR `local`, column-major).
//
// The entities are the demos' `/scene` (demo-log's scene.rs through SimEnv.scene_entities()): the
// robot as cylinders locked to the URDF links (`shoulder_link` … `tool0`), tile-sim's table, pad
// and target in `base`, the end effector in `tool0` and the object in `tile`. An entity's id is
// its scene item's name, numbered when the name repeats (`cup_0` … `cup_3`). The end effector's
// moving parts are found by those names and keep their geometry from the server:
// - `cup`: the suction cups, lit while {"kind":"suction","on":true};
// - `finger_left` / `finger_right`: drawn by tile-sim at the open limit; at run time each sits at
//   tool-y ±(opening / 2 + its half thickness) (tile-sim world.rs), from {"kind":"gripper",
//   "opening": m} or the screw task's gripper {"opening": m};
// - `nut`: the screw task's nut. Its frame (`tile`) already turns with the thread (the server's
//   pose); a plain cylinder turning shows nothing, so the page adds a notch on its rim and, while
//   {"kind":"screw","spin":±1} turns it, a ring of arrows around it going the same way.
import * as THREE from 'three';

const LIT = new THREE.Color(0.1, 0.95, 0.35);
const SPIN_RAD_PER_S = 2 * Math.PI; // the ring's animation (the nut's own angle is the server's)

/** The scene item's name of an entity id (`cup_3` → `cup`; `finger_left` stays). */
export function itemName(id) {
  return String(id ?? '').replace(/_\d+$/, '');
}

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
    this.entities = new Map(); // entity id → its group (in its frame)
    this.cups = []; // materials lit while suction is on
    this.fingers = []; // { group, sign, halfY, y0 }
    this.nut = null; // { group, radius, halfHeight }
    this.spinRing = null;
    this.spin = 0;
    this.ee = {};
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
    for (const c of [...this.root.children]) if (c !== this.target) this.root.remove(c);
    this.frames.clear();
    this.entities.clear();
    this.cups = [];
    this.fingers = [];
    this.nut = null;
    this.spinRing = null;
    this.setView(viewFromBase);
    for (const entity of entities ?? []) {
      const group = entityGroup(entity);
      this.frame(entity.frame_id ?? 'base').add(group);
      this.entities.set(entity.id ?? '', group);
      const name = itemName(entity.id);
      if (name === 'cup') {
        group.traverse((o) => o.material && this.cups.push(o.material));
      } else if (name === 'finger_left' || name === 'finger_right') {
        const c = entity.cubes?.[0];
        const y0 = c?.pose?.position?.y ?? 0;
        const sign = y0 !== 0 ? Math.sign(y0) : name === 'finger_left' ? 1 : -1;
        this.fingers.push({ name, group, sign, halfY: (c?.size?.y ?? 0) / 2, y0 });
      } else if (name === 'nut') {
        this.nut = this.decorateNut(group, entity.cylinders?.[0]);
      }
    }
  }

  /** A notch on the nut's rim (turns with the nut's frame) and the spin ring (hidden). */
  decorateNut(group, cyl) {
    const radius = (cyl?.size?.x ?? 0.02) / 2;
    const height = cyl?.size?.z ?? 0.01;
    const { position } = poseOf(cyl?.pose);
    const notch = new THREE.Mesh(unitBox, new THREE.MeshStandardMaterial({ color: 0x30343a }));
    notch.scale.set(radius * 0.5, radius * 0.35, height * 1.08);
    notch.position.set(position.x + radius * 0.8, position.y, position.z);
    notch.name = 'nut-notch';
    group.add(notch);
    const ring = new THREE.Group();
    ring.name = 'spin-ring';
    const r = radius * 2.2;
    const mat = new THREE.MeshBasicMaterial({ color: 0x38e0ff, side: THREE.DoubleSide });
    for (let k = 0; k < 3; k++) { // three arcs with arrow heads, counter-clockwise seen from +Z
      const a0 = (k * 2 * Math.PI) / 3;
      const arc = new THREE.Mesh(new THREE.TorusGeometry(r, radius * 0.14, 6, 16, 1.4), mat);
      arc.rotation.z = a0;
      ring.add(arc);
      const head = new THREE.Mesh(new THREE.ConeGeometry(radius * 0.35, radius * 0.8, 10), mat);
      const a1 = a0 + 1.4;
      head.position.set(r * Math.cos(a1), r * Math.sin(a1), 0);
      head.rotation.z = a1; // the cone's +Y along the tangent (counter-clockwise)
      ring.add(head);
    }
    ring.position.copy(position);
    ring.visible = false;
    // In the nut's frame beside the nut's group: it turns with the nut and, while spinning,
    // a little more each render frame the same way, so the direction shows at any nut speed.
    this.spinRing = ring;
    group.parent?.add(ring);
    return { group, radius, height };
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
    this.ee = ee;
    const lit = ee.kind === 'suction' && ee.on === true;
    for (const m of this.cups) m.emissive.copy(lit ? LIT : BLACK);
    if (Number.isFinite(ee.opening)) {
      for (const f of this.fingers) f.group.position.y = f.sign * (ee.opening / 2 + f.halfY) - f.y0;
    }
    this.spin = ee.kind === 'screw' && Number.isFinite(ee.spin) ? Math.sign(ee.spin) : 0;
    if (this.spinRing) {
      this.spinRing.visible = this.spin !== 0;
      // tile-sim: spin +1 tightens, turning the nut clockwise seen from above (about −Z); the
      // arrows are drawn counter-clockwise, so mirror them for +1.
      this.spinRing.scale.y = this.spin > 0 ? -1 : 1;
    }
    const t = state.target;
    this.target.visible = Array.isArray(t) && t.length >= 3;
    if (this.target.visible) this.target.position.set(t[0], t[1], t[2]);
    // the ghost of the target: yellow while the tool follows, red where it cannot get there
    const stuck = state.why === 'target unreachable';
    this.target.material.color.set(stuck ? 0xff3333 : 0xffcc00);
    this.target.scale.setScalar(stuck ? 1.6 : 1.0);
  }

  /** Per render frame: animate what moves between states (the spin ring). */
  tick(dt) {
    if (this.spin === 0 || !this.spinRing) return;
    this.spinRing.rotateZ(-this.spin * SPIN_RAD_PER_S * dt);
  }

  /** What is drawn, for tests: lit cups, finger centres (tool y, m), the nut's angle about its
   * frame's Z (rad), whether the spin ring shows, and each entity's first primitive's position in
   * its frame. */
  describe() {
    const fingers = {};
    for (const f of this.fingers) fingers[f.name] = f.y0 + f.group.position.y;
    let nutAngle = null;
    if (this.nut) {
      const q = this.nut.group.parent.quaternion;
      nutAngle = 2 * Math.atan2(q.z, q.w);
    }
    return {
      cups: this.cups.length,
      cupsLit: this.cups.filter((m) => m.emissive.equals(LIT)).length,
      fingers,
      nutAngle,
      spinRing: Boolean(this.spinRing?.visible),
      spinDirection: this.spin,
      viewFromBase: this.root.matrix.toArray(),
      entities: Object.fromEntries(
        [...this.entities].map(([id, g]) => [id, g.children[0]?.position.toArray() ?? null]),
      ),
      frames: Object.fromEntries([...this.frames].map(([k, f]) => [k, [...f.position.toArray(), ...f.quaternion.toArray()]])),
    };
  }
}

const BLACK = new THREE.Color(0, 0, 0);
