// The 2D floor plan: the site map, exhibits, doors and furniture as the robot estimates them, the
// planned path, the robot and the people.
export class MapView {
  constructor(canvas, site, { onClick } = {}) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.map = site.map;
    this.exhibits = site.exhibits;
    this.image = null;
    this.path = [];
    // doors and furniture in their estimated states: [{name, kind, outline: [[x, y], ...]}]
    this.objects = [];
    this.marker = null;
    this.obstacles = []; // the forward camera's obstacles [[x, y], ...] (cell centres), drawn orange
    this.obstacleCell = 0.1;
    this.truth = null; // debug overlay: the simulator's true people [[x, y], ...], drawn hollow
    this.turned = false;
    this.pixel = 1;
    this.labels = []; // the exhibit labels drawn last, as canvas rectangles (never overlapping)
    this.robotAt = null; // where the robot was drawn (canvas pixels)
    if (this.map) {
      this.fit();
      new ResizeObserver(() => this.fit()).observe(canvas.parentElement);
      const image = new Image();
      image.onload = () => { this.image = image; };
      image.src = "/api/map.png";
    }
    canvas.addEventListener("click", (event) => {
      if (!onClick || !this.map) return;
      const r = canvas.getBoundingClientRect();
      const world = this.toWorld(
        ((event.clientX - r.left) * canvas.width) / r.width,
        ((event.clientY - r.top) * canvas.height) / r.height,
      );
      const near = this.exhibits.find((e) => Math.hypot(e.x - world.x, e.y - world.y) < Math.max(0.6, (12 * this.pixel) / (this.scale / this.map.resolution)));
      onClick(world, near);
    });
  }

  // Size the canvas to its box's width and the map's shape: the map is drawn turned a quarter
  // turn (clockwise) when that shows it larger (a long building on a phone held upright), and the
  // canvas is as tall as the drawn map (at most maxHeight CSS pixels), so the map fills it.
  fit(maxHeight = window.innerHeight * 0.7) {
    if (!this.map) return;
    const ratio = window.devicePixelRatio || 1;
    const width = Math.max(100, this.canvas.parentElement.clientWidth - 1);
    if (width === this.fitted) return; // (the observer also reports the size this sets)
    this.fitted = width;
    const [cols, rows] = this.cropSize;
    const upright = Math.min(width / cols, maxHeight / rows);
    const turned = Math.min(width / rows, maxHeight / cols);
    this.turned = turned > upright * 1.05;
    const k = Math.max(upright, turned);
    const [w, h] = this.turned ? [rows * k, cols * k] : [cols * k, rows * k];
    this.canvas.style.width = `${Math.round(w)}px`;
    this.canvas.style.height = `${Math.round(h)}px`;
    this.canvas.width = Math.round(w * ratio);
    this.canvas.height = Math.round(h * ratio);
    this.pixel = ratio;
  }

  // The mapped part of the floor-plan image (server's known_bounds): [u0, v0, u1, v1].
  get crop() {
    return this.map.crop || [0, 0, this.map.cols, this.map.rows];
  }

  get cropSize() {
    const [u0, v0, u1, v1] = this.crop;
    return [u1 - u0, v1 - v0];
  }

  get scale() {
    const [cols, rows] = this.cropSize;
    const [w, h] = this.turned ? [rows, cols] : [cols, rows];
    return Math.min(this.canvas.width / w, this.canvas.height / h);
  }

  // Top-left corner of the drawn map in canvas pixels.
  get offset() {
    const k = this.scale;
    const [cols, rows] = this.cropSize;
    const [w, h] = this.turned ? [rows, cols] : [cols, rows];
    return [(this.canvas.width - w * k) / 2, (this.canvas.height - h * k) / 2];
  }

  // The world direction (unit vector) that points up on the screen: the 3D view looks the same way.
  get screenUp() {
    const yaw = this.map ? this.map.origin[2] : 0;
    const [gx, gy] = this.turned ? [-1, 0] : [0, 1];
    return [Math.cos(yaw) * gx - Math.sin(yaw) * gy, Math.sin(yaw) * gx + Math.cos(yaw) * gy];
  }

  // Image pixel (u right, v down; row 0 = largest y of the grid frame) -> canvas pixels.
  imageToCanvas(u, v) {
    const k = this.scale;
    const [ox, oy] = this.offset;
    const [u0, v0, , v1] = this.crop;
    return this.turned ? [ox + (v1 - v) * k, oy + (u - u0) * k] : [ox + (u - u0) * k, oy + (v - v0) * k];
  }

  canvasToImage(px, py) {
    const k = this.scale;
    const [ox, oy] = this.offset;
    const [u0, v0, , v1] = this.crop;
    const a = (px - ox) / k, b = (py - oy) / k;
    return this.turned ? [u0 + b, v1 - a] : [u0 + a, v0 + b];
  }

  // Screen angle of a world heading (canvas y points down).
  screenAngle(theta) {
    return -(theta - this.map.origin[2]) + (this.turned ? Math.PI / 2 : 0);
  }

  // World (m) -> canvas pixels.
  toCanvas(x, y) {
    const [ox, oy, yaw] = this.map.origin;
    const c = Math.cos(yaw), s = Math.sin(yaw);
    const dx = x - ox, dy = y - oy;
    const gx = c * dx + s * dy, gy = -s * dx + c * dy;
    return this.imageToCanvas(gx / this.map.resolution, this.map.rows - gy / this.map.resolution);
  }

  toWorld(px, py) {
    const [ox, oy, yaw] = this.map.origin;
    const [u, v] = this.canvasToImage(px, py);
    const gx = u * this.map.resolution;
    const gy = (this.map.rows - v) * this.map.resolution;
    const c = Math.cos(yaw), s = Math.sin(yaw);
    return { x: ox + c * gx - s * gy, y: oy + s * gx + c * gy };
  }

  // Doors and furniture where the robot believes they are (the states its world model holds: the
  // latest well-observed estimates). A door leaf is drawn at least 4 px thick.
  drawObjects(ctx, px1) {
    for (const o of this.objects) {
      if (o.outline.length < 2) continue;
      ctx.beginPath();
      o.outline.forEach(([x, y], i) => {
        const [px, py] = this.toCanvas(x, y);
        if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
      });
      ctx.closePath();
      const color = o.kind === "door" ? "#7a3b0c" : "#2b6e3f";
      ctx.fillStyle = color;
      ctx.strokeStyle = color;
      ctx.lineWidth = (o.kind === "door" ? 4 : 1.5) * px1;
      ctx.fill();
      ctx.stroke();
    }
  }

  draw(bodies) {
    const ctx = this.ctx;
    ctx.fillStyle = "#ddd";
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    if (!this.map) return;
    const k = this.scale;
    if (this.image) {
      const [u0, v0] = this.crop;
      const [cw, ch] = this.cropSize;
      const [x0, y0] = this.imageToCanvas(u0, v0);
      ctx.save();
      ctx.imageSmoothingEnabled = false;
      ctx.translate(x0, y0);
      if (this.turned) ctx.rotate(Math.PI / 2);
      ctx.drawImage(this.image, u0, v0, cw, ch, 0, 0, cw * k, ch * k);
      ctx.restore();
    }
    const px1 = this.pixel;
    ctx.font = `${Math.round(12 * px1)}px system-ui, sans-serif`;
    ctx.lineJoin = "round";
    const marks = this.exhibits.map((e) => this.toCanvas(e.x, e.y));
    for (const [px, py] of marks) {
      ctx.fillStyle = "#c80";
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 1.5 * px1;
      ctx.beginPath();
      ctx.arc(px, py, 5 * px1, 0, 2 * Math.PI);
      ctx.fill();
      ctx.stroke();
    }
    // Labels placed greedily: beside, above or below the marker, wherever they overlap no label
    // and no marker drawn so far and stay inside the canvas; a label that fits nowhere is left out
    // (its exhibit is still listed beside the map).
    const placed = [];
    const pad = 2 * px1;
    const hit = (a, b) => a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
    const markBoxes = marks.map(([x, y]) => ({ x: x - 5 * px1, y: y - 5 * px1, w: 10 * px1, h: 10 * px1 }));
    for (const b of bodies) { // the robot's ring is kept clear of labels too
      if (b.id !== 0) continue;
      const [x, y] = this.toCanvas(b.x, b.y);
      const r = 1.8 * Math.max(9 * px1, (0.3 / this.map.resolution) * k);
      markBoxes.push({ x: x - r, y: y - r, w: 2 * r, h: 2 * r });
    }
    this.exhibits.forEach((e, i) => {
      const [px, py] = marks[i];
      const w = ctx.measureText(e.name).width + 2 * pad, h = 14 * px1 + 2 * pad;
      const d = 7 * px1;
      const spots = [[px + d, py - h / 2], [px - d - w, py - h / 2], [px - w / 2, py - d - h],
        [px - w / 2, py + d], [px + d, py - h], [px + d, py], [px - d - w, py - h], [px - d - w, py]];
      for (const [x, y] of spots) {
        const box = { x, y, w, h };
        if (x < 0 || y < 0 || x + w > this.canvas.width || y + h > this.canvas.height) continue;
        if (placed.some((b) => hit(b, box)) || markBoxes.some((b) => hit(b, box))) continue;
        placed.push({ ...box, text: e.name });
        break;
      }
    });
    ctx.textBaseline = "middle";
    for (const b of placed) {
      ctx.fillStyle = "#fffd";
      ctx.fillRect(b.x, b.y, b.w, b.h);
      ctx.fillStyle = "#630";
      ctx.fillText(b.text, b.x + pad, b.y + b.h / 2);
    }
    this.labels = placed.map(({ x, y, w, h, text }) => ({ x, y, w, h, text }));
    if (this.obstacles.length) {
      // what the robot's forward camera found where its laser sees nothing (glass, tables)
      ctx.fillStyle = "#f60c";
      const side = Math.max(2 * px1, (this.obstacleCell / this.map.resolution) * k);
      for (const [x, y] of this.obstacles) {
        const [px, py] = this.toCanvas(x, y);
        ctx.fillRect(px - side / 2, py - side / 2, side, side);
      }
      ctx.fillStyle = "#fffd";
      ctx.fillRect(0, this.canvas.height - 18 * px1, 190 * px1, 18 * px1);
      ctx.fillStyle = "#c40";
      ctx.textBaseline = "middle";
      ctx.fillText("orange: obstacles the camera found", 4 * px1, this.canvas.height - 9 * px1);
    }
    this.drawObjects(ctx, px1);
    if (this.path.length > 1) {
      ctx.strokeStyle = "#08f";
      ctx.lineWidth = 2.5 * px1;
      ctx.beginPath();
      this.path.forEach(([x, y], i) => {
        const [px, py] = this.toCanvas(x, y);
        if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
      });
      ctx.stroke();
    }
    if (this.marker) {
      const [px, py] = this.toCanvas(this.marker.x, this.marker.y);
      ctx.strokeStyle = "#f0f";
      ctx.lineWidth = 2 * px1;
      ctx.beginPath();
      ctx.arc(px, py, 6 * px1, 0, 2 * Math.PI);
      ctx.stroke();
    }
    for (const b of bodies) {
      if (b.id === 0) continue;
      const [px, py] = this.toCanvas(b.x, b.y);
      ctx.fillStyle = `hsl(${(b.id * 67) % 360} 45% 50% / 0.8)`;
      ctx.beginPath();
      ctx.arc(px, py, Math.max(2.5 * px1, (0.22 / this.map.resolution) * k), 0, 2 * Math.PI);
      ctx.fill();
    }
    if (this.truth) {
      ctx.strokeStyle = "#000a";
      ctx.lineWidth = 1 * px1;
      for (const [x, y] of this.truth) {
        const [px, py] = this.toCanvas(x, y);
        ctx.beginPath();
        ctx.arc(px, py, Math.max(3 * px1, (0.22 / this.map.resolution) * k), 0, 2 * Math.PI);
        ctx.stroke();
      }
      ctx.fillStyle = "#ffd400";
      ctx.fillRect(0, 0, 150 * px1, 18 * px1);
      ctx.fillStyle = "#000";
      ctx.fillText("DEBUG: simulator truth", 4 * px1, 9 * px1);
    }
    // the robot last, on top of people and labels: a ring that shows it at any zoom, in a crowd
    this.robotAt = null;
    for (const b of bodies) {
      if (b.id !== 0) continue;
      const [px, py] = this.toCanvas(b.x, b.y);
      const r = Math.max(9 * px1, (0.3 / this.map.resolution) * k);
      this.robotAt = { x: px, y: py, r: r * 1.8 };
      ctx.save();
      ctx.translate(px, py);
      ctx.strokeStyle = "#d00";
      ctx.lineWidth = 2.5 * px1;
      ctx.fillStyle = "#fffb";
      ctx.beginPath();
      ctx.arc(0, 0, r * 1.8, 0, 2 * Math.PI);
      ctx.fill();
      ctx.stroke();
      ctx.rotate(this.screenAngle(b.theta));
      ctx.fillStyle = "#d00";
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 2 * px1;
      ctx.beginPath();
      ctx.moveTo(r, 0);
      ctx.lineTo(-r * 0.7, r * 0.7);
      ctx.lineTo(-r * 0.7, -r * 0.7);
      ctx.closePath();
      ctx.fill();
      ctx.stroke();
      ctx.restore();
    }
  }
}
