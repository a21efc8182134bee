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

  get scale() {
    return Math.min(this.canvas.width / this.map.cols, this.canvas.height / this.map.rows);
  }

  // World (m) -> canvas pixels; the image is north up (row 0 = largest y of the grid frame).
  toCanvas(x, y) {
    const [ox, oy, yaw] = this.map.origin;
    const c = Math.cos(yaw), s = Math.sin(yaw);
    const dx = x - ox, dy = y - oy;
    const gx = c * dx + s * dy, gy = -s * dx + c * dy;
    const k = this.scale;
    return [(gx / this.map.resolution) * k, (this.map.rows - gy / this.map.resolution) * k];
  }

  toWorld(px, py) {
    const [ox, oy, yaw] = this.map.origin;
    const k = this.scale;
    const gx = (px / k) * this.map.resolution;
    const gy = (this.map.rows - py / k) * this.map.resolution;
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
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(this.image, 0, 0, this.map.cols * k, this.map.rows * k);
    }
    for (const e of this.exhibits) {
      const [px, py] = this.toCanvas(e.x, e.y);
      ctx.fillStyle = "#c80";
      ctx.fillRect(px - 4, py - 4, 8, 8);
      ctx.fillStyle = "#630";
      ctx.font = "11px sans-serif";
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
      ctx.beginPath();
      ctx.arc(px, py, 6, 0, 2 * Math.PI);
      ctx.stroke();
    }
    for (const b of bodies) {
      const [px, py] = this.toCanvas(b.x, b.y);
      if (b.id === 0) {
        const r = Math.max(6, (0.3 / this.map.resolution) * k);
        ctx.save();
        ctx.translate(px, py);
        ctx.rotate(-b.theta + this.map.origin[2]);
        ctx.fillStyle = "#d00";
        ctx.beginPath();
        ctx.moveTo(r, 0);
        ctx.lineTo(-r * 0.7, r * 0.7);
        ctx.lineTo(-r * 0.7, -r * 0.7);
        ctx.closePath();
        ctx.fill();
        ctx.restore();
      } else {
        ctx.fillStyle = `hsl(${(b.id * 67) % 360} 70% 45%)`;
        ctx.beginPath();
        ctx.arc(px, py, Math.max(3, (0.25 / this.map.resolution) * k), 0, 2 * Math.PI);
        ctx.fill();
      }
    }
  }
}
