// The telemetry chart: measured (solid) and setpoint (dashed) per joint over the last seconds.
// Samples are stored as they arrive (100 a second); drawing happens at most once per frame.

export const JOINT_COLORS = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2', '#17becf'];

export class Chart {
  constructor(canvas, dof, seconds = 10) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.dof = dof;
    this.seconds = seconds;
    // A ring with room for 10 s at up to 400 samples a second.
    this.cap = Math.ceil(seconds * 400);
    this.t = new Float64Array(this.cap);
    this.m = new Float32Array(this.cap * dof);
    this.s = new Float32Array(this.cap * dof);
    this.head = 0; // index of the next write
    this.len = 0;
    this.dirty = true;
    new ResizeObserver(() => { this.dirty = true; }).observe(canvas);
  }

  push(time, measured, setpoints) {
    if (this.len > 0) {
      const last = this.t[(this.head - 1 + this.cap) % this.cap];
      // Controller time went back: a restarted controller, the old curve means nothing now.
      if (time < last) this.len = 0;
    }
    const i = this.head;
    this.t[i] = time;
    for (let j = 0; j < this.dof; j++) {
      this.m[i * this.dof + j] = measured[j];
      this.s[i * this.dof + j] = setpoints[j];
    }
    this.head = (i + 1) % this.cap;
    this.len = Math.min(this.len + 1, this.cap);
    this.dirty = true;
  }

  draw() {
    if (!this.dirty) return;
    this.dirty = false;
    const c = this.canvas, ctx = this.ctx;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(c.clientWidth * dpr)), h = Math.max(1, Math.round(c.clientHeight * dpr));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const W = c.clientWidth, H = c.clientHeight;
    ctx.clearRect(0, 0, W, H);
    ctx.font = '11px system-ui, sans-serif';
    const left = 44, right = 6, top = 6, bottom = 16;
    const pw = W - left - right, ph = H - top - bottom;
    if (pw < 10 || ph < 10) return;

    if (this.len === 0) {
      ctx.fillStyle = '#68707a';
      ctx.fillText('waiting for telemetry…', left + 8, top + 14);
      return;
    }
    const newest = (this.head - 1 + this.cap) % this.cap;
    const tEnd = this.t[newest], tStart = tEnd - this.seconds;
    // First sample inside the window.
    let n = 0;
    while (n < this.len && this.t[(newest - n + this.cap) % this.cap] >= tStart) n++;
    const first = (newest - n + 1 + this.cap) % this.cap;

    let lo = Infinity, hi = -Infinity;
    for (let k = 0; k < n; k++) {
      const i = (first + k) % this.cap;
      for (let j = 0; j < this.dof; j++) {
        const a = this.m[i * this.dof + j], b = this.s[i * this.dof + j];
        if (a < lo) lo = a; if (a > hi) hi = a;
        if (b < lo) lo = b; if (b > hi) hi = b;
      }
    }
    if (!(hi - lo >= 0.2)) { const mid = isFinite(lo) ? (lo + hi) / 2 : 0; lo = mid - 0.1; hi = mid + 0.1; }
    const pad = (hi - lo) * 0.08;
    lo -= pad; hi += pad;
    const X = (t) => left + (t - tStart) / this.seconds * pw;
    const Yv = (v) => top + (hi - v) / (hi - lo) * ph;

    // Axes: a line per second, about five value lines.
    ctx.lineWidth = 1;
    ctx.strokeStyle = '#e4e7eb';
    ctx.fillStyle = '#68707a';
    ctx.beginPath();
    for (let s = 0; s <= this.seconds; s++) {
      const x = Math.round(left + s / this.seconds * pw) + 0.5;
      ctx.moveTo(x, top); ctx.lineTo(x, top + ph);
    }
    const step = niceStep((hi - lo) / 5);
    const vals = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi; v += step) vals.push(v);
    for (const v of vals) { const y = Math.round(Yv(v)) + 0.5; ctx.moveTo(left, y); ctx.lineTo(left + pw, y); }
    ctx.stroke();
    ctx.textAlign = 'right';
    ctx.textBaseline = 'middle';
    const digits = step < 0.1 ? 2 : 1;
    for (const v of vals) ctx.fillText(v.toFixed(digits), left - 4, Yv(v));
    ctx.textAlign = 'center';
    ctx.textBaseline = 'top';
    for (let s = 0; s <= this.seconds; s += 2) {
      ctx.textAlign = s === this.seconds ? 'right' : 'center';
      ctx.fillText(s === this.seconds ? 'now' : `-${this.seconds - s} s`, left + s / this.seconds * pw, top + ph + 3);
    }
    ctx.save();
    ctx.translate(10, top + ph / 2); ctx.rotate(-Math.PI / 2); ctx.fillText('rad', 0, -6);
    ctx.restore();

    ctx.save();
    ctx.beginPath(); ctx.rect(left, top, pw, ph); ctx.clip();
    // At most about one point per pixel: no visible loss, bounded work however fast data comes.
    const stride = Math.max(1, Math.floor(n / (pw * 1.5)));
    for (const [buf, dash, width] of [[this.s, [5, 4], 1.2], [this.m, [], 1.6]]) {
      ctx.setLineDash(dash);
      ctx.lineWidth = width;
      for (let j = 0; j < this.dof; j++) {
        ctx.strokeStyle = JOINT_COLORS[j % JOINT_COLORS.length];
        ctx.beginPath();
        for (let k = 0; k < n; k += stride) {
          const i = (first + k) % this.cap;
          const x = X(this.t[i]), y = Yv(buf[i * this.dof + j]);
          if (k === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
        }
        const y = Yv(buf[newest * this.dof + j]);
        ctx.lineTo(X(tEnd), y);
        ctx.stroke();
      }
    }
    ctx.restore();
    ctx.setLineDash([]);
    ctx.strokeStyle = '#b9bfc6';
    ctx.strokeRect(left + 0.5, top + 0.5, pw - 1, ph - 1);
  }
}

function niceStep(raw) {
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const f = raw / p;
  return (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10) * p;
}
