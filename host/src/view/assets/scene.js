// The 3D view: the arm drawn from its telemetry frames, the IK preview, the target gizmo,
// the planned path of a played file and the arm's meshes. Z is up, units are metres. A rig's view
// draws every arm at its base in the world frame (the telemetry's frames are in it already); the
// preview and the target belong to the arm the controls drive (`select`).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { TransformControls } from 'three/addons/controls/TransformControls.js';
import { STLLoader } from 'three/addons/loaders/STLLoader.js';
import { authHeaders } from './api.js';

const Y = new THREE.Vector3(0, 1, 0);
const _a = new THREE.Vector3();
const _d = new THREE.Vector3();

/** The API's quaternions are [w, x, y, z]; three.js takes (x, y, z, w). */
function setQuat(out, q) { return out.set(q[1], q[2], q[3], q[0]); }
function getQuat(q) { return [q.w, q.x, q.y, q.z]; }

// One geometry per shape, scaled per use, so a chain costs no geometry per update.
const unitCylinder = new THREE.CylinderGeometry(1, 1, 1, 20);
const unitCone = new THREE.ConeGeometry(1, 1, 20);
const unitSphere = new THREE.SphereGeometry(1, 24, 16);

/** Stretches a unit cylinder (along +Y) from a to b with the given radius. */
function placeSegment(mesh, a, b, radius) {
  _d.subVectors(b, a);
  const len = _d.length();
  mesh.visible = len > 1e-6;
  if (!mesh.visible) return;
  mesh.position.addVectors(a, b).multiplyScalar(0.5);
  mesh.quaternion.setFromUnitVectors(Y, _d.divideScalar(len));
  mesh.scale.set(radius, len, radius);
}

/** An arrow along +Y of a group: a shaft and a cone, `length` long. */
function makeArrow(material, length, radius) {
  const g = new THREE.Group();
  const shaft = new THREE.Mesh(unitCylinder, material);
  shaft.scale.set(radius, length * 0.75, radius);
  shaft.position.y = length * 0.375;
  const tip = new THREE.Mesh(unitCone, material);
  tip.scale.set(radius * 2.4, length * 0.25, radius * 2.4);
  tip.position.y = length * 0.875;
  g.add(shaft, tip);
  return g;
}

/** Red, green and blue arrows along the group's X, Y and Z. */
function makeTriad(length, radius, opacity = 1) {
  const g = new THREE.Group();
  const dirs = [[0xe53935, new THREE.Vector3(1, 0, 0)], [0x43a047, new THREE.Vector3(0, 1, 0)], [0x1e88e5, new THREE.Vector3(0, 0, 1)]];
  for (const [color, dir] of dirs) {
    const m = new THREE.MeshStandardMaterial({ color, roughness: 0.6, transparent: opacity < 1, opacity });
    const a = makeArrow(m, length, radius);
    a.quaternion.setFromUnitVectors(Y, dir);
    g.add(a);
  }
  return g;
}

/**
 * A kinematic chain drawn from dof+1 frames (joint 1..dof, then the tool):
 * links from the base origin through every frame origin, each joint's axis, a tool triad.
 * `base`: the base's {p, q} in the scene (a rig's arm), or null for the scene's origin.
 */
class Chain {
  constructor(arm, size, { colors, opacity = 1, linkColor = 0x59636e, axes = true, base = null }) {
    this.arm = arm;
    this.size = size;
    this.group = new THREE.Group();
    const transparent = opacity < 1;
    const mat = (color) => new THREE.MeshStandardMaterial({
      color, roughness: 0.55, metalness: 0.1, transparent, opacity, depthWrite: !transparent,
    });
    this.linkMaterial = mat(linkColor);
    this.points = [base ? new THREE.Vector3().fromArray(base.p) : new THREE.Vector3()];
    this.links = [];
    for (let i = 0; i <= arm.dof; i++) {
      this.points.push(new THREE.Vector3());
      const m = new THREE.Mesh(unitCylinder, this.linkMaterial);
      this.links.push(m);
      this.group.add(m);
    }
    // Each joint: a drum around its axis (revolute) and an arrow showing the axis' sign.
    this.joints = [];
    arm.joints.forEach((j, i) => {
      const g = new THREE.Group();
      const axis = new THREE.Vector3(...(j.axis || [0, 0, 1]));
      if (axis.lengthSq() < 1e-12) axis.set(0, 0, 1);
      axis.normalize();
      const align = new THREE.Quaternion().setFromUnitVectors(Y, axis);
      const color = colors[i % colors.length];
      const inner = new THREE.Group();
      inner.quaternion.copy(align);
      if (axes) {
        if (j.kind !== 'prismatic') {
          const drum = new THREE.Mesh(unitCylinder, mat(color));
          drum.scale.set(size.link * 1.7, size.link * 3.2, size.link * 1.7);
          inner.add(drum);
        }
        const arrow = makeArrow(mat(j.kind === 'prismatic' ? color : 0x2b2f33), size.link * 6, size.link * 0.3);
        inner.add(arrow);
      } else {
        const ball = new THREE.Mesh(unitSphere, mat(color));
        ball.scale.setScalar(size.link * 1.3);
        inner.add(ball);
      }
      g.add(inner);
      this.joints.push(g);
      this.group.add(g);
    });
    this.tool = makeTriad(size.triad, size.link * 0.3, opacity);
    this.group.add(this.tool);
    this.frameQuats = [];
  }

  setColor(color) { this.linkMaterial.color.set(color); }

  /** frames: [{p, q}] dof+1 of them, as in telemetry. */
  update(frames) {
    const n = Math.min(frames.length, this.arm.dof + 1);
    for (let i = 0; i < n; i++) this.points[i + 1].fromArray(frames[i].p);
    for (let i = 0; i < this.links.length; i++) {
      if (i < n) placeSegment(this.links[i], this.points[i], this.points[i + 1], this.size.linkRadius);
      else this.links[i].visible = false;
    }
    for (let i = 0; i < this.joints.length; i++) {
      const g = this.joints[i];
      g.visible = i < n;
      if (!g.visible) continue;
      g.position.fromArray(frames[i].p);
      setQuat(g.quaternion, frames[i].q);
    }
    this.tool.visible = n === this.arm.dof + 1;
    if (this.tool.visible) {
      this.tool.position.fromArray(frames[n - 1].p);
      setQuat(this.tool.quaternion, frames[n - 1].q);
    }
  }
}

export class ArmScene {
  /**
   * canvas: the <canvas>; arms: [{arm: GET /api/arm, base: {p, q} or null}], one for the one-arm
   * view, each arm of a rig at its base otherwise; colors: one CSS colour per joint;
   * onTargetChange(): the gizmo moved (called on every change);
   * onTargetRelease(): the user let go of the gizmo; onError(text).
   */
  constructor(canvas, arms, { colors, onTargetChange, onTargetRelease, onError }) {
    this.canvas = canvas;
    this.arms = arms;
    this.selected = 0;
    this.dirty = true;
    const reaches = arms.map((a) => a.arm.reach).filter((r) => r > 0);
    const reach = reaches.length ? Math.max(...reaches) : 0.5;
    // With meshes the links shrink to a skeleton inside them.
    const meshes = arms.some((a) => (a.arm.meshes || []).length > 0);
    this.size = { link: reach * 0.022, linkRadius: reach * (meshes ? 0.008 : 0.022), triad: reach * 0.14 };
    // Where the bases are: the camera looks at their middle from far enough to see them all.
    const bases = arms.map((a) => new THREE.Vector3().fromArray(a.base ? a.base.p : [0, 0, 0]));
    const centre = bases.reduce((c, b) => c.add(b), new THREE.Vector3()).divideScalar(bases.length);
    const spread = Math.max(...bases.map((b) => b.distanceTo(centre)));
    const far = Math.max(...bases.map((b) => Math.hypot(b.x, b.y)));
    const view = reach + spread;

    const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.renderer = renderer;

    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0xdfe2e6);
    this.scene = scene;
    scene.add(new THREE.HemisphereLight(0xffffff, 0x9aa0a6, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(view * 2, -view * 3, view * 5);
    scene.add(sun);

    // GridHelper lies in XZ; rotated into the arm's XY floor. 0.1 m cells, at least 1 m across.
    const half = Math.max(0.5, Math.ceil((reach * 1.25 + far) * 10) / 10);
    const grid = new THREE.GridHelper(2 * half, Math.round(20 * half), 0x8a9099, 0xc2c7cd);
    grid.rotation.x = Math.PI / 2;
    scene.add(grid);
    const worldAxes = new THREE.AxesHelper(reach * 0.25);
    worldAxes.position.z = 0.0005;
    scene.add(worldAxes);

    const camera = new THREE.PerspectiveCamera(45, 1, reach * 0.01, view * 100);
    camera.up.set(0, 0, 1);
    camera.position.set(centre.x + view * 1.1, centre.y - view * 1.4, centre.z + view * 0.9);
    this.camera = camera;
    const orbit = new OrbitControls(camera, canvas);
    orbit.target.set(centre.x + reach * 0.25, centre.y, centre.z + reach * 0.2);
    orbit.enableDamping = false;
    orbit.update();
    orbit.addEventListener('change', () => { this.dirty = true; });

    // Per arm: its base, its chain, its preview, its setpoints' tool, its meshes.
    this.drawn = arms.map(({ arm, base }) => {
      const placed = (object) => {
        if (base) {
          object.position.fromArray(base.p);
          setQuat(object.quaternion, base.q);
        }
        return object;
      };
      // The base: a flat disc, so the chain visibly stands on something.
      const disc = new THREE.Mesh(unitCylinder, new THREE.MeshStandardMaterial({ color: 0x3d4650, roughness: 0.7 }));
      disc.quaternion.setFromUnitVectors(Y, new THREE.Vector3(0, 0, 1));
      disc.scale.set(this.size.link * 3.5, this.size.link * 0.8, this.size.link * 3.5);
      disc.position.z = this.size.link * 0.4;
      const stand = placed(new THREE.Group());
      stand.add(disc);
      scene.add(stand);

      const chain = new Chain(arm, this.size, { colors, base });
      scene.add(chain.group);
      chain.group.visible = false;

      const preview = new Chain(arm, this.size, { colors, opacity: 0.35, linkColor: 0x1f6feb, axes: false, base });
      preview.group.visible = false;
      scene.add(preview.group);

      // Where the setpoints put the tool: a faint ball (the server sends the setpoints' tool only).
      const ghost = new THREE.Mesh(unitSphere, new THREE.MeshBasicMaterial({
        color: 0x7b1fa2, transparent: true, opacity: 0.35, depthWrite: false,
      }));
      ghost.scale.setScalar(this.size.link * 1.2);
      ghost.visible = false;
      scene.add(ghost);

      // Frame groups for the meshes: 0 is the base, k is telemetry frames[k-1].
      const meshFrames = [];
      for (let k = 0; k <= arm.dof; k++) {
        const g = k === 0 ? placed(new THREE.Group()) : new THREE.Group();
        g.visible = k === 0;
        meshFrames.push(g);
        scene.add(g);
      }
      // The collision geometry (GET /api/collision), shown with the checkbox: bodies in frame
      // groups as the meshes are (0 the base, k telemetry frames[k-1]), obstacles in the base frame.
      const collisionFrames = [];
      for (let k = 0; k <= arm.dof; k++) {
        const g = k === 0 ? placed(new THREE.Group()) : new THREE.Group();
        g.visible = false;
        collisionFrames.push(g);
        scene.add(g);
      }
      const obstacles = placed(new THREE.Group());
      obstacles.visible = false;
      scene.add(obstacles);
      return { arm, chain, preview, ghost, meshFrames, disc, collisionFrames, obstacles, collision: null };
    });
    this.showingCollision = false;
    this.floorHalf = half;
    this.markSelected();
    this.drawn.forEach((d) => this.loadMeshes(d, d.arm.meshes || [], onError));
    // The one-arm view's names for the one arm.
    this.chain = this.drawn[0].chain;
    this.preview = this.drawn[0].preview;

    // The target the user drags; its gizmo is TransformControls.
    this.target = new THREE.Group();
    this.targetMaterial = new THREE.MeshStandardMaterial({ color: 0xf57c00, roughness: 0.4, emissive: 0x331a00 });
    const ball = new THREE.Mesh(unitSphere, this.targetMaterial);
    ball.scale.setScalar(this.size.link * 1.6);
    this.target.add(ball);
    this.targetTriad = null;
    if (arms.some((a) => a.arm.orientation)) {
      this.targetTriad = makeTriad(this.size.triad * 0.8, this.size.link * 0.25, 0.8);
      this.targetTriad.visible = !!arms[0].arm.orientation;
      this.target.add(this.targetTriad);
    }
    this.target.visible = false;
    scene.add(this.target);

    const gizmo = new TransformControls(camera, canvas);
    gizmo.setSize(0.75);
    gizmo.attach(this.target);
    gizmo.enabled = false;
    gizmo.addEventListener('dragging-changed', (e) => {
      orbit.enabled = !e.value;
      if (!e.value) onTargetRelease();
    });
    gizmo.addEventListener('objectChange', () => { this.dirty = true; onTargetChange(); });
    gizmo.addEventListener('change', () => { this.dirty = true; });
    this.gizmo = gizmo;
    this.gizmoHelper = gizmo.getHelper();
    this.gizmoHelper.visible = false;
    scene.add(this.gizmoHelper);

    this.path = null;

    const resize = () => {
      const w = canvas.clientWidth, h = canvas.clientHeight;
      if (w === 0 || h === 0) return;
      renderer.setSize(w, h, false);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
      this.dirty = true;
    };
    new ResizeObserver(resize).observe(canvas);
    resize();
  }

  /** The arm the preview and the target belong to (a rig's view): its index in `arms`. */
  select(index) {
    if (!this.drawn[index]) return;
    this.drawn[this.selected].preview.group.visible = false;
    this.selected = index;
    if (this.targetTriad) this.targetTriad.visible = !!this.arms[index].arm.orientation;
    this.markSelected();
    this.dirty = true;
  }

  /** Of several arms, the driven one stands on a base of the accent colour. */
  markSelected() {
    if (this.drawn.length < 2) return;
    this.drawn.forEach((d, i) => d.disc.material.color.set(i === this.selected ? 0x1f6feb : 0x3d4650));
  }

  loadMeshes(drawn, meshes, onError) {
    if (meshes.length === 0) return;
    const loader = new STLLoader().setRequestHeader(authHeaders());
    const material = new THREE.MeshStandardMaterial({ color: 0xf2f2ee, roughness: 0.65, metalness: 0.05 });
    for (const m of meshes) {
      const frame = drawn.meshFrames[m.frame];
      if (!frame) { onError(`mesh ${m.url}: frame ${m.frame} is not in 0..${drawn.arm.dof}`); continue; }
      loader.load(m.url, (geometry) => {
        if (!geometry.hasAttribute('normal')) geometry.computeVertexNormals();
        const mesh = new THREE.Mesh(geometry, material);
        if (m.p) mesh.position.fromArray(m.p);
        if (m.q) setQuat(mesh.quaternion, m.q);
        if (m.scale) mesh.scale.fromArray(m.scale);
        frame.add(mesh);
        this.dirty = true;
      }, undefined, (err) => onError(`cannot load the mesh ${m.url}: ${err && err.message ? err.message : err}`));
    }
  }

  /**
   * Arm `index`'s collision geometry as GET /api/collision gives it: each body a capsule (a
   * cylinder and two balls) on its joint's frame, each obstacle in the base frame (a table a
   * translucent plane at its height).
   */
  setCollision(geometry, index = 0) {
    const d = this.drawn[index];
    if (!d) return;
    const clear = (g) => { while (g.children.length) g.remove(g.children[0]); };
    d.collisionFrames.forEach(clear);
    clear(d.obstacles);
    d.collision = geometry;
    const translucent = (color, opacity) => new THREE.MeshStandardMaterial({
      color, roughness: 0.6, transparent: true, opacity, depthWrite: false, side: THREE.DoubleSide,
    });
    const bodyMaterial = translucent(0xff9800, 0.35);
    const obstacleMaterial = translucent(0x546e7a, 0.45);
    const capsule = (group, a, b, radius, material) => {
      const pa = new THREE.Vector3().fromArray(a), pb = new THREE.Vector3().fromArray(b);
      const tube = new THREE.Mesh(unitCylinder, material);
      placeSegment(tube, pa, pb, radius);
      group.add(tube);
      for (const p of pa.distanceTo(pb) > 1e-9 ? [pa, pb] : [pa]) {
        const ball = new THREE.Mesh(unitSphere, material);
        ball.position.copy(p);
        ball.scale.setScalar(radius);
        group.add(ball);
      }
    };
    for (const b of geometry.bodies || []) {
      const frame = d.collisionFrames[b.link === null || b.link === undefined ? 0 : b.link + 1];
      if (frame) capsule(frame, b.a, b.b, b.radius, bodyMaterial);
    }
    const size = 2 * this.floorHalf;
    for (const o of geometry.obstacles || []) {
      if (o.shape === 'box') {
        const m = new THREE.Mesh(new THREE.BoxGeometry(...o.size), obstacleMaterial);
        m.position.fromArray(o.centre);
        if (o.rotation) {
          const r = o.rotation;
          m.quaternion.setFromRotationMatrix(new THREE.Matrix4().set(
            r[0][0], r[0][1], r[0][2], 0, r[1][0], r[1][1], r[1][2], 0, r[2][0], r[2][1], r[2][2], 0, 0, 0, 0, 1));
        }
        d.obstacles.add(m);
      } else if (o.shape === 'sphere') {
        capsule(d.obstacles, o.centre, o.centre, o.radius, obstacleMaterial);
      } else if (o.shape === 'capsule') {
        capsule(d.obstacles, o.a, o.b, o.radius, obstacleMaterial);
      } else if (o.shape === 'table' || o.shape === 'plane') {
        // PlaneGeometry faces +Z: turned to the normal, at the plane's offset along it.
        const normal = new THREE.Vector3().fromArray(o.shape === 'table' ? [0, 0, 1] : o.normal);
        const m = new THREE.Mesh(new THREE.PlaneGeometry(size, size), translucent(0x8d6e63, 0.25));
        m.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), normal);
        m.position.copy(normal).multiplyScalar(o.shape === 'table' ? o.height : o.offset);
        d.obstacles.add(m);
      }
    }
    this.showCollision(this.showingCollision);
  }

  /** Shows or hides every arm's collision geometry (the checkbox). */
  showCollision(on) {
    this.showingCollision = on;
    for (const d of this.drawn) {
      d.obstacles.visible = on;
      d.collisionFrames.forEach((g, k) => { g.visible = on && (k === 0 || d.chain.group.visible); });
    }
    this.dirty = true;
  }

  /** What is drawn of the collision geometry (for the browser tests): per arm, whether it shows,
   * the body meshes and the obstacle meshes. */
  drawnCollision() {
    return this.drawn.map((d) => ({
      shown: d.obstacles.visible,
      bodies: d.collisionFrames.reduce((n, g) => n + g.children.length, 0),
      obstacles: d.obstacles.children.length,
      names: d.collision ? (d.collision.obstacles || []).map((o) => o.name) : [],
    }));
  }

  /** frames: arm `index`'s telemetry frames. */
  setFrames(frames, index = 0) {
    const d = this.drawn[index];
    if (!d) return;
    d.chain.group.visible = true;
    d.chain.update(frames);
    for (let k = 1; k < d.collisionFrames.length; k++) {
      const f = frames[k - 1];
      const g = d.collisionFrames[k];
      g.visible = this.showingCollision && !!f;
      if (!f) continue;
      g.position.fromArray(f.p);
      setQuat(g.quaternion, f.q);
    }
    for (let k = 1; k < d.meshFrames.length; k++) {
      const f = frames[k - 1];
      const g = d.meshFrames[k];
      g.visible = !!f;
      if (!f) continue;
      g.position.fromArray(f.p);
      setQuat(g.quaternion, f.q);
    }
    this.dirty = true;
  }

  setToolSetpoint(p, index = 0) {
    const ghost = this.drawn[index] && this.drawn[index].ghost;
    if (!ghost) return;
    ghost.visible = !!p;
    if (p) ghost.position.fromArray(p);
    this.dirty = true;
  }

  /** The selected arm's preview: frames null hides it; reachable colours it blue, else red. */
  setPreview(frames, reachable) {
    const preview = this.drawn[this.selected].preview;
    preview.group.visible = !!frames;
    if (frames) {
      preview.update(frames);
      preview.setColor(reachable ? 0x1f6feb : 0xd32f2f);
    }
    this.dirty = true;
  }

  setTargetReachable(reachable) {
    this.targetMaterial.color.set(reachable === false ? 0xd32f2f : 0xf57c00);
    this.targetMaterial.emissive.set(reachable === false ? 0x400000 : 0x331a00);
    this.dirty = true;
  }

  /** Places the target (position [x,y,z], orientation [w,x,y,z] or null) and shows its gizmo. */
  setTarget(position, orientation) {
    this.target.position.fromArray(position);
    if (orientation) setQuat(this.target.quaternion, orientation);
    if (!this.target.visible) {
      this.target.visible = true;
      this.gizmoHelper.visible = true;
      this.gizmo.enabled = true;
    }
    this.dirty = true;
  }

  targetPosition() { return this.target.position.toArray(); }
  targetOrientation() { return getQuat(this.target.quaternion); }
  targetShown() { return this.target.visible; }

  setGizmoMode(mode) { this.gizmo.setMode(mode); this.dirty = true; }

  /** points: [[x,y,z], ...] or null. */
  setPath(points) {
    if (this.path) {
      this.scene.remove(this.path);
      this.path.geometry.dispose();
      this.path = null;
    }
    if (points && points.length > 0) {
      const geom = new THREE.BufferGeometry().setFromPoints(points.map((p) => new THREE.Vector3(...p)));
      const group = new THREE.Group();
      group.add(new THREE.Line(geom, new THREE.LineBasicMaterial({ color: 0x8e24aa })));
      group.add(new THREE.Points(geom, new THREE.PointsMaterial({ color: 0x8e24aa, size: 4, sizeAttenuation: false })));
      group.geometry = geom;
      this.path = group;
      this.scene.add(group);
    }
    this.dirty = true;
  }

  /** The target's centre in page (CSS) pixels. */
  targetScreen() {
    this.target.getWorldPosition(_a);
    return this.screen(_a);
  }

  /** A point of the scene in page (CSS) pixels. */
  screen(point) {
    this.camera.updateMatrixWorld();
    _a.copy(point).project(this.camera);
    const r = this.canvas.getBoundingClientRect();
    return {
      x: r.left + window.scrollX + (_a.x + 1) / 2 * r.width,
      y: r.top + window.scrollY + (1 - _a.y) / 2 * r.height,
    };
  }

  /** What is drawn of each arm (for the browser tests): whether its chain shows, where its
   * base and frames are, and where on the page its first link is (the middle of frames 1 and 2). */
  drawnArms() {
    return this.drawn.map((d) => {
      const points = d.chain.points.map((p) => p.toArray());
      const middle = new THREE.Vector3().fromArray(points[1]).add(new THREE.Vector3().fromArray(points[2])).multiplyScalar(0.5);
      return { shown: d.chain.group.visible, base: points[0], points, link: this.screen(middle) };
    });
  }

  render() {
    if (!this.dirty) return;
    this.dirty = false;
    this.renderer.render(this.scene, this.camera);
  }
}
