// Decoder of tourbot's live stream: the browser side of tourbot/web/stream.py (same layout).
// A keyframe carries every body (each with its age); a delta only the bodies whose dead reckoning
// drifted.
const KEYFRAME = 1;
const DELTA = 2;
const TWO_PI = 2 * Math.PI;

function wrap(a) {
  const w = a - TWO_PI * Math.round(a / TWO_PI);
  return w <= -Math.PI ? w + TWO_PI : w;
}

export class StreamDecoder {
  constructor(config) {
    this.q = config; // position_quantum, velocity_quantum, turn_quantum, time_quantum, horizon
    this.epoch = null;
    this.t = 0;
    this.bodies = new Map(); // id -> {t, x, y, vx, vy, theta, omega}
  }

  feed(buffer) {
    const view = new DataView(buffer);
    let o = 0;
    const kind = view.getUint8(o); o += 1;
    let epoch = this.epoch;
    let bodies = new Map(this.bodies);
    if (kind === KEYFRAME) {
      epoch = view.getFloat64(o, true); o += 8;
      bodies = new Map();
    } else if (kind !== DELTA || epoch === null) {
      throw new Error(`unexpected stream message type ${kind}`);
    }
    const ticks = view.getUint16(o, true); o += 2;
    const count = view.getUint8(o); o += 1;
    const t = this.unwrap(epoch, ticks);
    const q = this.q;
    for (let k = 0; k < count; k++) {
      const id = view.getUint16(o, true);
      const body = {
        t,
        x: view.getInt16(o + 2, true) * q.position_quantum,
        y: view.getInt16(o + 4, true) * q.position_quantum,
        vx: view.getInt8(o + 6) * q.velocity_quantum,
        vy: view.getInt8(o + 7) * q.velocity_quantum,
        theta: 0,
        omega: 0,
      };
      o += 8;
      if (id === 0) {
        body.theta = wrap((view.getUint16(o, true) * TWO_PI) / 65536);
        body.omega = view.getInt8(o + 2) * q.turn_quantum;
        o += 3;
      }
      if (kind === KEYFRAME) { // the body as it was sent, age time quanta before t
        body.t = t - view.getUint16(o, true) * q.time_quantum;
        o += 2;
      }
      bodies.set(id, body);
    }
    const removed = view.getUint8(o); o += 1;
    for (let k = 0; k < removed; k++) {
      bodies.delete(view.getUint16(o, true));
      o += 2;
    }
    if (o !== buffer.byteLength) throw new Error("trailing bytes in a stream message");
    this.epoch = epoch;
    this.t = t;
    this.bodies = bodies;
    return t;
  }

  unwrap(epoch, ticks) {
    const q = this.q.time_quantum;
    if (epoch !== this.epoch) return epoch + ticks * q;
    const base = Math.round((this.t - epoch) / q);
    const delta = (((ticks - base) % 65536) + 65536) % 65536;
    return epoch + (base + delta) * q;
  }

  // Every body dead-reckoned to server time t, at most the horizon past its last message: what
  // the server assumes this client shows.
  at(t) {
    const out = [];
    for (const [id, b] of this.bodies) {
      const dt = Math.max(0, Math.min(t - b.t, this.q.horizon));
      out.push({
        id,
        x: b.x + b.vx * dt,
        y: b.y + b.vy * dt,
        vx: b.vx,
        vy: b.vy,
        theta: wrap(b.theta + b.omega * dt),
      });
    }
    return out;
  }
}
