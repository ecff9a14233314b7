// Tracked hands: the 25 WebXR joints of each XRHand → Float32Array(75) positions in the XR
// `local` reference space, plus joint spheres for the scene.
import * as THREE from 'three';
import { JOINTS, FLOATS_PER_HAND } from './protocol.js';

/** WebXR Hand Input joint order (the order of the XRHand map, and of the wire format). */
export const JOINT_NAMES = [
  'wrist',
  'thumb-metacarpal', 'thumb-phalanx-proximal', 'thumb-phalanx-distal', 'thumb-tip',
  ...['index-finger', 'middle-finger', 'ring-finger', 'pinky-finger'].flatMap((f) => [
    `${f}-metacarpal`, `${f}-phalanx-proximal`, `${f}-phalanx-intermediate`,
    `${f}-phalanx-distal`, `${f}-tip`,
  ]),
];

/** Reads one hand per frame; its buffers are reused, so copy what must outlive the frame. */
export class HandReader {
  constructor() {
    this.transforms = new Float32Array(JOINTS * 16);
    this.radii = new Float32Array(JOINTS);
    this.positions = new Float32Array(FLOATS_PER_HAND);
    this.spacesOf = new WeakMap(); // XRHand → its 25 XRJointSpaces in JOINT_NAMES order
  }

  spaces(hand) {
    let s = this.spacesOf.get(hand);
    if (!s) {
      s = JOINT_NAMES.map((name) => hand.get(name));
      this.spacesOf.set(hand, s);
    }
    return s;
  }

  /**
   * Fill this.positions (and this.radii) from `hand` in `refSpace`. Returns false when the pose is
   * unavailable: XRFrame.fillPoses returns false if any joint is untracked (WebXR Hand Input §).
   * fillPoses writes one column-major 4×4 per joint; its translation is elements 12..14.
   */
  read(frame, hand, refSpace) {
    const spaces = this.spaces(hand);
    if (spaces.some((s) => !s)) return false;
    let ok;
    if (typeof frame.fillPoses === 'function') {
      ok = frame.fillPoses(spaces, refSpace, this.transforms);
      if (ok && typeof frame.fillJointRadii === 'function') {
        frame.fillJointRadii(spaces, this.radii);
      }
    } else {
      ok = true; // UAs without the batch calls: one getJointPose per joint
      for (let i = 0; i < JOINTS && ok; i++) {
        const pose = frame.getJointPose(spaces[i], refSpace);
        if (!pose) ok = false;
        else {
          this.transforms.set(pose.transform.matrix, i * 16);
          this.radii[i] = pose.radius ?? 0.01;
        }
      }
    }
    if (!ok) return false;
    for (let i = 0; i < JOINTS; i++) {
      this.positions[3 * i] = this.transforms[16 * i + 12];
      this.positions[3 * i + 1] = this.transforms[16 * i + 13];
      this.positions[3 * i + 2] = this.transforms[16 * i + 14];
    }
    return true;
  }
}

/** 25 spheres drawn where the joints are (already in `local`, so straight under the scene). */
export class HandSpheres {
  constructor(scene, color) {
    const geometry = new THREE.SphereGeometry(1, 10, 8);
    const material = new THREE.MeshStandardMaterial({ color, roughness: 0.6 });
    this.mesh = new THREE.InstancedMesh(geometry, material, JOINTS);
    this.mesh.frustumCulled = false;
    this.mesh.visible = false;
    this.matrix = new THREE.Matrix4();
    scene.add(this.mesh);
  }

  update(positions, radii) {
    if (!positions) {
      this.mesh.visible = false;
      return;
    }
    for (let i = 0; i < JOINTS; i++) {
      const r = radii && radii[i] > 0 ? radii[i] : 0.008;
      this.matrix.makeScale(r, r, r);
      this.matrix.setPosition(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
      this.mesh.setMatrixAt(i, this.matrix);
    }
    this.mesh.instanceMatrix.needsUpdate = true;
    this.mesh.visible = true;
  }
}
