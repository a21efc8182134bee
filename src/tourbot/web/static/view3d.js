// The 3D view (Burgard et al., section 6.1.1): the site, the robot and the tracked people as
// avatars, rendered in the browser from the compact state stream; any viewpoint, at run time.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const WALL_HEIGHT = 1.2;
const DOOR_HEIGHT = 2.0;
const FURNITURE_HEIGHT = 0.5;

export class View3D {
  // screenUp(): the world direction shown up on the 2D map; the bird's-eye views look the same way.
  constructor(canvas, site, { screenUp = () => [0, 1] } = {}) {
    this.canvas = canvas;
    this.screenUp = screenUp;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xbfd4e6);
    this.camera = new THREE.PerspectiveCamera(60, canvas.width / canvas.height, 0.1, 500);
    this.camera.up.set(0, 0, 1); // the map's z is up
    this.controls = new OrbitControls(this.camera, canvas);
    this.preset = "bird";
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x556677, 2.0));
    const sun = new THREE.DirectionalLight(0xffffff, 1.2);
    sun.position.set(20, -10, 30);
    this.scene.add(sun);
    this.avatars = new Map();
    this.objects = new THREE.Group(); // doors and furniture in their estimated states
    this.scene.add(this.objects);
    this.robot = this.makeRobot();
    this.scene.add(this.robot);
    this.center = new THREE.Vector3(0, 0, 0);
    if (site.map) this.buildSite(site);
    for (const e of site.exhibits) this.addExhibit(e);
    this.fit();
    new ResizeObserver(() => this.fit()).observe(canvas.parentElement);
    this.setPreset("bird");
  }

  // The canvas at its box's width, 16:9.
  fit() {
    const width = Math.max(100, this.canvas.parentElement.clientWidth);
    if (width === this.fitted) return;
    this.fitted = width;
    const height = Math.round((width * 9) / 16);
    this.renderer.setSize(width, height, false);
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
  }

  // Where a world point is drawn, in normalised device coordinates (-1..1 across the canvas).
  project(x, y, z = 0) {
    this.camera.updateMatrixWorld();
    const v = new THREE.Vector3(x, y, z).project(this.camera);
    return { x: v.x, y: v.y, z: v.z };
  }

  // Camera above the point (x, y), back along the 2D map's "down" so that up on the screen is
  // up on the map, at height h looking at the point.
  lookDown(x, y, h, back) {
    const [ux, uy] = this.screenUp();
    this.camera.position.set(x - ux * back, y - uy * back, h);
    this.camera.lookAt(x, y, 0);
    this.controls.target.set(x, y, 0);
  }

  buildSite(site) {
    const m = site.map;
    const [ox, oy, yaw] = m.origin;
    const frame = new THREE.Group(); // the grid frame placed in the world
    frame.position.set(ox, oy, 0);
    frame.rotation.z = yaw;
    const w = m.cols * m.resolution, h = m.rows * m.resolution;
    const texture = new THREE.TextureLoader().load("/api/map.png");
    texture.magFilter = THREE.NearestFilter;
    texture.colorSpace = THREE.SRGBColorSpace;
    const floor = new THREE.Mesh(new THREE.PlaneGeometry(w, h), new THREE.MeshLambertMaterial({ map: texture }));
    floor.position.set(w / 2, h / 2, 0);
    frame.add(floor);
    // Walls: the map's occupied cells merged into boxes [col0, row0, col1, row1) (see /api/walls).
    fetch("/api/walls").then((r) => r.json()).then(({ boxes, cell }) => {
      const size = cell * m.resolution;
      const geometry = new THREE.BoxGeometry(1, 1, 1);
      const material = new THREE.MeshLambertMaterial({ color: 0x8a8f99 });
      const walls = new THREE.InstancedMesh(geometry, material, Math.max(1, boxes.length));
      const matrix = new THREE.Matrix4();
      boxes.forEach(([c0, r0, c1, r1], i) => {
        const w = (c1 - c0) * size, h = (r1 - r0) * size;
        matrix.makeScale(w, h, WALL_HEIGHT);
        matrix.setPosition(c0 * size + w / 2, r0 * size + h / 2, WALL_HEIGHT / 2);
        walls.setMatrixAt(i, matrix);
      });
      walls.count = boxes.length;
      this.walls = walls;
      frame.add(walls);
    });
    this.scene.add(frame);
    const c = Math.cos(yaw), s = Math.sin(yaw);
    this.center.set(ox + c * w / 2 - s * h / 2, oy + s * w / 2 + c * h / 2, 0);
    this.extent = Math.max(w, h);
  }

  addExhibit(e) {
    const stand = new THREE.Mesh(
      new THREE.CylinderGeometry(0.25, 0.3, 0.9, 16),
      new THREE.MeshLambertMaterial({ color: 0xcc8800 }),
    );
    stand.rotation.x = Math.PI / 2;
    // x, y, theta is where the robot stands to present the exhibit, facing it: the stand is ahead.
    stand.position.set(e.x + Math.cos(e.theta), e.y + Math.sin(e.theta), 0.45);
    this.scene.add(stand);
  }

  makeRobot() {
    const robot = new THREE.Group();
    const body = new THREE.Mesh(
      new THREE.CylinderGeometry(0.3, 0.3, 1.0, 24),
      new THREE.MeshLambertMaterial({ color: 0xcc2222 }),
    );
    body.rotation.x = Math.PI / 2;
    body.position.z = 0.5;
    const head = new THREE.Mesh(new THREE.SphereGeometry(0.18, 16, 12), new THREE.MeshLambertMaterial({ color: 0xeeeeee }));
    head.position.set(0.1, 0, 1.15);
    const nose = new THREE.Mesh(new THREE.ConeGeometry(0.08, 0.25, 12), new THREE.MeshLambertMaterial({ color: 0x222222 }));
    nose.rotation.z = -Math.PI / 2;
    nose.position.set(0.32, 0, 1.15);
    // a ring on the floor and a mast: the robot is found at once from above, in any crowd
    const ring = new THREE.Mesh(new THREE.RingGeometry(0.55, 0.75, 32), new THREE.MeshBasicMaterial({ color: 0xff2020 }));
    ring.position.z = 0.02;
    const mast = new THREE.Mesh(new THREE.CylinderGeometry(0.05, 0.05, 1.2, 8), new THREE.MeshBasicMaterial({ color: 0xff2020 }));
    mast.rotation.x = Math.PI / 2;
    mast.position.z = 1.8;
    robot.add(body, head, nose, ring, mast);
    return robot;
  }

  makeAvatar(id) {
    const color = new THREE.Color(`hsl(${(id * 67) % 360}, 70%, 45%)`);
    const avatar = new THREE.Group();
    const torso = new THREE.Mesh(new THREE.CapsuleGeometry(0.2, 0.9, 4, 12), new THREE.MeshLambertMaterial({ color }));
    torso.rotation.x = Math.PI / 2;
    torso.position.z = 0.75;
    const head = new THREE.Mesh(new THREE.SphereGeometry(0.14, 12, 10), new THREE.MeshLambertMaterial({ color: 0xf0c8a0 }));
    head.position.z = 1.55;
    avatar.add(torso, head);
    this.scene.add(avatar);
    return avatar;
  }

  // bird: above the robot (about 16 m of floor in view), following it; orbit: the whole building,
  // free to turn; robot: its own eyes; follow: behind it.
  setPreset(name) {
    this.preset = name;
    this.controls.enabled = name === "orbit";
    if (name === "orbit") {
      const d = this.extent || 20;
      const fit = (0.55 * d) / Math.tan((this.camera.fov * Math.PI) / 360) / Math.min(1, this.camera.aspect);
      this.lookDown(this.center.x, this.center.y, fit * 0.95, fit * 0.3);
      this.controls.update();
    }
  }

  // Doors and furniture as the robot estimates them: each outline extruded (a door to 2 m, a
  // piece of furniture to 0.5 m). Rebuilt per message:
  // messages come only when something moved.
  setObjects(objects) {
    for (const mesh of this.objects.children) { mesh.geometry.dispose(); mesh.material.dispose(); }
    this.objects.clear();
    for (const o of objects) {
      if (o.outline.length < 3) continue;
      const shape = new THREE.Shape(o.outline.map(([x, y]) => new THREE.Vector2(x, y)));
      const door = o.kind === "door";
      const geometry = new THREE.ExtrudeGeometry(shape, { depth: door ? DOOR_HEIGHT : FURNITURE_HEIGHT, bevelEnabled: false });
      const material = new THREE.MeshLambertMaterial({ color: door ? 0x7a3b0c : 0x2b6e3f });
      const mesh = new THREE.Mesh(geometry, material);
      mesh.name = o.name;
      this.objects.add(mesh);
    }
  }

  update(bodies) {
    const seen = new Set();
    for (const b of bodies) {
      if (b.id === 0) {
        this.robot.position.set(b.x, b.y, 0);
        this.robot.rotation.z = b.theta;
        continue;
      }
      seen.add(b.id);
      let avatar = this.avatars.get(b.id);
      if (!avatar) {
        avatar = this.makeAvatar(b.id);
        this.avatars.set(b.id, avatar);
      }
      avatar.position.set(b.x, b.y, 0);
      if (Math.hypot(b.vx, b.vy) > 0.1) avatar.rotation.z = Math.atan2(b.vy, b.vx);
    }
    for (const [id, avatar] of this.avatars) {
      if (!seen.has(id)) {
        this.scene.remove(avatar);
        this.avatars.delete(id);
      }
    }
    const r = this.robot.position, th = this.robot.rotation.z;
    const c = Math.cos(th), s = Math.sin(th);
    if (this.preset === "bird") {
      this.lookDown(r.x, r.y, 14, 5);
    } else if (this.preset === "robot") {
      this.camera.position.set(r.x + 0.35 * c, r.y + 0.35 * s, 1.3);
      this.camera.lookAt(r.x + 5 * c, r.y + 5 * s, 1.0);
    } else if (this.preset === "follow") {
      this.camera.position.set(r.x - 4 * c, r.y - 4 * s, 3.0);
      this.camera.lookAt(r.x + c, r.y + s, 0.8);
    }
    this.renderer.render(this.scene, this.camera);
  }
}
