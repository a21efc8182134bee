// The 2D floor plan: the site map, exhibits, the planned path, the robot and the people.
export class MapView {
  constructor(canvas, site, { onClick } = {}) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.map = site.map;
    this.exhibits = site.exhibits;
    this.image = null;
    this.path = [];
    this.marker = null;
    if (this.map) {
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
      const near = this.exhibits.find((e) => Math.hypot(e.x - world.x, e.y - world.y) < 0.6);
      onClick(world, near);
    });
  }

  // A map taller than the canvas's shape is shown turned a quarter turn (clockwise), so that a
  // long, narrow building fills the view; the map is centred in the canvas.
  get turned() {
    const wide = this.canvas.width >= this.canvas.height;
    return wide !== this.map.cols >= this.map.rows;
  }

  get scale() {
    const [w, h] = this.turned ? [this.map.rows, this.map.cols] : [this.map.cols, this.map.rows];
    return Math.min(this.canvas.width / w, this.canvas.height / h);
  }

  // Top-left corner of the drawn map in canvas pixels.
  get offset() {
    const k = this.scale;
    const [w, h] = this.turned ? [this.map.rows, this.map.cols] : [this.map.cols, this.map.rows];
    return [(this.canvas.width - w * k) / 2, (this.canvas.height - h * k) / 2];
  }

  // Image pixel (u right, v down; row 0 = largest y of the grid frame) -> canvas pixels.
  imageToCanvas(u, v) {
    const k = this.scale;
    const [ox, oy] = this.offset;
    return this.turned ? [ox + (this.map.rows - v) * k, oy + u * k] : [ox + u * k, oy + v * k];
  }

  canvasToImage(px, py) {
    const k = this.scale;
    const [ox, oy] = this.offset;
    const a = (px - ox) / k, b = (py - oy) / k;
    return this.turned ? [b, this.map.rows - a] : [a, b];
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

  draw(bodies) {
    const ctx = this.ctx;
    ctx.fillStyle = "#ddd";
    ctx.fillRect(0, 0, this.canvas.width, this.canvas.height);
    if (!this.map) return;
    const k = this.scale;
    if (this.image) {
      const [x0, y0] = this.imageToCanvas(0, 0);
      ctx.save();
      ctx.imageSmoothingEnabled = false;
      ctx.translate(x0, y0);
      if (this.turned) ctx.rotate(Math.PI / 2);
      ctx.drawImage(this.image, 0, 0, this.map.cols * k, this.map.rows * k);
      ctx.restore();
    }
    ctx.font = "11px sans-serif";
    ctx.lineJoin = "round";
    for (const e of this.exhibits) {
      const [px, py] = this.toCanvas(e.x, e.y);
      ctx.fillStyle = "#c80";
      ctx.fillRect(px - 4, py - 4, 8, 8);
      ctx.strokeStyle = "#fffc";
      ctx.lineWidth = 3;
      ctx.strokeText(e.name, px + 6, py - 6);
      ctx.fillStyle = "#630";
      ctx.fillText(e.name, px + 6, py - 6);
    }
    if (this.path.length > 1) {
      ctx.strokeStyle = "#08f";
      ctx.lineWidth = 2;
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
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(px, py, 6, 0, 2 * Math.PI);
      ctx.stroke();
    }
    for (const b of bodies) {
      if (b.id === 0) continue;
      const [px, py] = this.toCanvas(b.x, b.y);
      ctx.fillStyle = `hsl(${(b.id * 67) % 360} 70% 45%)`;
      ctx.beginPath();
      ctx.arc(px, py, Math.max(3, (0.25 / this.map.resolution) * k), 0, 2 * Math.PI);
      ctx.fill();
    }
    // the robot last, on top of the people, with a halo so it stands out in a crowd
    for (const b of bodies) {
      if (b.id !== 0) continue;
      const [px, py] = this.toCanvas(b.x, b.y);
      const r = Math.max(9, (0.3 / this.map.resolution) * k);
      ctx.save();
      ctx.translate(px, py);
      ctx.fillStyle = "#fff8";
      ctx.beginPath();
      ctx.arc(0, 0, r * 1.5, 0, 2 * Math.PI);
      ctx.fill();
      ctx.rotate(this.screenAngle(b.theta));
      ctx.fillStyle = "#d00";
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 2;
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
