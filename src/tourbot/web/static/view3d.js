// The 3D view (Burgard et al., section 6.1.1): the site, the robot and the tracked people as
// avatars, rendered in the browser from the compact state stream; any viewpoint, at run time.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const WALL_HEIGHT = 1.2;

export class View3D {
  constructor(canvas, site) {
    this.canvas = canvas;
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
    this.robot = this.makeRobot();
    this.scene.add(this.robot);
    this.center = new THREE.Vector3(0, 0, 0);
    if (site.map) this.buildSite(site);
    for (const e of site.exhibits) this.addExhibit(e);
    this.setPreset("bird");
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
    fetch("/api/walls").then((r) => r.json()).then(({ runs }) => {
      const geometry = new THREE.BoxGeometry(1, 1, 1);
      const material = new THREE.MeshLambertMaterial({ color: 0x8a8f99 });
      const walls = new THREE.InstancedMesh(geometry, material, Math.max(1, runs.length));
      const matrix = new THREE.Matrix4();
      runs.forEach(([c0, row, c1], i) => {
        const length = (c1 - c0) * m.resolution;
        matrix.makeScale(length, m.resolution, WALL_HEIGHT);
        matrix.setPosition((c0 * m.resolution) + length / 2, (row + 0.5) * m.resolution, WALL_HEIGHT / 2);
        walls.setMatrixAt(i, matrix);
      });
      walls.count = runs.length;
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
    robot.add(body, head, nose);
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

  setPreset(name) {
    this.preset = name;
    this.controls.enabled = name === "orbit" || name === "bird";
    if (name === "bird" || name === "orbit") {
      const d = this.extent || 20;
      this.camera.position.set(this.center.x, this.center.y - d * 0.35, d * 0.9);
      this.controls.target.copy(this.center);
      this.controls.update();
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
    if (this.preset === "robot") {
      this.camera.position.set(r.x + 0.35 * c, r.y + 0.35 * s, 1.3);
      this.camera.lookAt(r.x + 5 * c, r.y + 5 * s, 1.0);
    } else if (this.preset === "follow") {
      this.camera.position.set(r.x - 4 * c, r.y - 4 * s, 3.0);
      this.camera.lookAt(r.x + c, r.y + s, 0.8);
    }
    this.renderer.render(this.scene, this.camera);
  }
}
