// The page of `armctl view`: wiring between the server (api.js), the 3D view (scene.js),
// the chart (chart.js) and the controls in index.html. The API it uses: docs/view.md's
// "Seeing the arm". In a rig's view (`armctl view --rig`, GET /api/rig not null) every arm is
// drawn at its base and listed with its telemetry; the controls drive the arm picked in the list
// (its requests go to /api/arm/NAME/...), and STOP stops every arm.
import { ArmScene } from './scene.js';
import { Chart, JOINT_COLORS } from './chart.js';
import { post, getJSON, connectTelemetry, onRequestError } from './api.js';

const $ = (id) => document.getElementById(id);

let rig = null;            // GET /api/rig: null in the one-arm view
let arms = [];             // per arm: {name, arm, base, latest, fresh, chart, arrivals, lastServerError, row}
let selected = 0;          // the arm the controls drive
let arm = null;            // its GET /api/arm
let scene = null;
let chart = null;          // its chart
let latest = null;         // its newest telemetry object
let connected = false;
const sliders = [];        // per joint: {input, measured, setpoint, dragging, hold}
let gripperDragging = false;
let targetInitialised = false;

// For the browser tests (host/tests/view/e2e.mjs, rig.mjs): where to grab the gizmo, where the
// target is, the arms and what is drawn of them.
window.armView = {
  targetScreen: () => (scene && scene.targetShown() ? scene.targetScreen() : null),
  target: () => (scene && scene.targetShown() ? scene.targetPosition() : null),
  rig: () => (rig ? rig.name : null),
  arms: () => arms.map((a) => a.name),
  selected: () => (arms[selected] ? arms[selected].name : null),
  drawnArms: () => (scene ? scene.drawnArms() : []),
  drawnCollision: () => (scene ? scene.drawnCollision() : []),
};

/** The path of an endpoint of the arm the controls drive. */
function apiPath(endpoint) {
  return rig ? `/api/arm/${encodeURIComponent(arms[selected].name)}/${endpoint}` : `/api/${endpoint}`;
}

function showError(text) {
  const el = $('error');
  el.textContent = text;
  el.title = `at ${new Date().toLocaleTimeString()}`;
}
onRequestError(showError);

function setText(el, text) {
  if (el.textContent !== text) el.textContent = text;
}

const fmt = (v, d = 3) => (typeof v === 'number' && isFinite(v) ? v.toFixed(d) : '—');

async function start() {
  for (;;) {
    let asked = '/api/rig';
    try {
      rig = await getJSON(asked);
      if (rig) {
        arms = rig.arms.map((a) => ({ name: a.name, arm: a.arm, base: a.base }));
      } else {
        asked = '/api/arm';
        arms = [{ name: null, arm: await getJSON(asked), base: null }];
      }
      break;
    } catch (e) {
      showError(`cannot read the arm from the server (${asked}): ${e.message}; retrying`);
      await new Promise((r) => setTimeout(r, 1000));
    }
  }
  for (const a of arms) Object.assign(a, { latest: null, fresh: false, arrivals: [], lastServerError: null, row: null });
  arm = arms[0].arm;
  buildRig();
  showArmName();
  buildJoints();
  buildGripper();
  try {
    scene = new ArmScene($('view3d'), arms.map((a) => ({ arm: a.arm, base: a.base })), {
      colors: JOINT_COLORS,
      onTargetChange: targetMovedByGizmo,
      onTargetRelease: () => scheduleTarget(),
      onError: showError,
    });
  } catch (e) {
    // Without WebGL there is no page worth showing; say so rather than leave a blank canvas.
    showError(`cannot draw the arm in 3D (WebGL): ${e.message}`);
    throw e;
  }
  for (const a of arms) a.chart = new Chart($('chart'), a.arm.dof);
  chart = arms[0].chart;
  buildLegend();
  wireGripper();
  wireTarget();
  wireButtons();
  wirePlay();
  wireCollision();
  connectTelemetry({ onMessage: onTelemetry, onClose: onDisconnect });
  requestAnimationFrame(frame);
}

// ---- joints ------------------------------------------------------------------------------

function limit(v, fallback) { return typeof v === 'number' && isFinite(v) ? v : fallback; }

function buildJoints() {
  const box = $('joints');
  box.textContent = '';
  sliders.length = 0;
  arm.joints.forEach((j, i) => {
    const row = document.createElement('div');
    row.className = 'joint';
    const lower = limit(j.lower, -Math.PI), upper = limit(j.upper, Math.PI);
    // A range input snaps to min + k * step: with min on the 0.001 grid (rounded inwards) the
    // values sent are round and never beyond a limit.
    const min = Math.ceil(lower * 1000 - 1e-6) / 1000, max = Math.floor(upper * 1000 + 1e-6) / 1000;
    const unit = j.kind === 'prismatic' ? 'm' : 'rad';
    row.innerHTML = `
      <span class="name"><span class="swatch"></span><span class="label"></span></span>
      <span class="nums"><span class="m" id="joint-${i}-measured">—</span> / <span id="joint-${i}-setpoint">—</span> ${unit}</span>
      <input type="range" id="joint-${i}" min="${min}" max="${max}" step="0.001" value="${Math.min(Math.max(0, min), max)}">
      <div class="limits"><span>${lower.toFixed(2)}</span><span>${upper.toFixed(2)}</span></div>`;
    row.querySelector('.swatch').style.background = JOINT_COLORS[i % JOINT_COLORS.length];
    row.querySelector('.label').textContent = j.name || `joint ${i + 1}`;
    box.appendChild(row);
    const s = {
      input: row.querySelector('input'),
      measured: row.querySelector(`#joint-${i}-measured`),
      setpoint: row.querySelector(`#joint-${i}-setpoint`),
      dragging: false,
      hold: null,
    };
    s.input.addEventListener('pointerdown', () => { s.dragging = true; });
    s.input.addEventListener('input', () => { s.dragging = true; });
    // No `change` follows a press that did not move the slider.
    s.input.addEventListener('pointerup', () => { s.dragging = false; });
    s.input.addEventListener('change', () => { s.dragging = false; sendJoints(); });
    sliders.push(s);
  });
}

async function sendJoints() {
  const q = sliders.map((s) => parseFloat(s.input.value));
  // Until the setpoints get there, the sliders keep showing what was asked for: otherwise they
  // would jump back to the setpoints of the moment and a second slider's release would send
  // a half-done first joint.
  const until = performance.now() + 8000;
  sliders.forEach((s, i) => { s.hold = { value: q[i], until }; });
  const r = await post(apiPath('joints'), { q });
  if (!r.ok) releaseSliders();
}

function followSetpoints(t) {
  const now = performance.now();
  sliders.forEach((s, i) => {
    const sp = t.setpoints ? t.setpoints[i] : undefined;
    setText(s.measured, fmt(t.measured ? t.measured[i] : undefined));
    setText(s.setpoint, fmt(sp));
    if (s.dragging || typeof sp !== 'number') return;
    if (s.hold) {
      if (Math.abs(sp - s.hold.value) < 0.002 || now > s.hold.until || t.state === 'TorqueOff') s.hold = null;
      else return;
    }
    const v = String(sp);
    if (s.input.value !== v) s.input.value = v;
  });
}

// ---- gripper -----------------------------------------------------------------------------

function buildGripper() {
  $('gripper-section').hidden = !arm.gripper;
  if (!arm.gripper) return;
  const g = $('gripper');
  g.min = limit(arm.gripper.min_percent, 0);
  g.max = limit(arm.gripper.max_percent, 100);
}

function wireGripper() {
  const g = $('gripper');
  g.addEventListener('pointerdown', () => { gripperDragging = true; });
  g.addEventListener('input', () => { gripperDragging = true; setText($('gripper-state'), `${g.value} %`); });
  g.addEventListener('pointerup', () => { gripperDragging = false; });
  g.addEventListener('change', () => {
    gripperDragging = false;
    post(apiPath('gripper'), { percent: parseFloat(g.value) });
  });
}

// ---- target ------------------------------------------------------------------------------

const targetInputs = () => [$('target-x'), $('target-y'), $('target-z')];

function showTargetInInputs() {
  const p = scene.targetPosition();
  targetInputs().forEach((el, i) => {
    // Leave alone the box the user is typing in.
    // Math.abs keeps "-0.000" out of the box.
    if (document.activeElement !== el) el.value = (Math.abs(p[i]) < 5e-4 ? 0 : p[i]).toFixed(3);
  });
}

function targetMovedByGizmo() {
  showTargetInInputs();
  scheduleTarget();
}

function targetBody(go) {
  const body = { position: scene.targetPosition(), go };
  if (arm.orientation) body.orientation = scene.targetOrientation();
  return body;
}

// At most one request in flight and one every 50 ms (20 Hz); the last position always goes.
const targetLink = { inFlight: false, pending: false, last: 0, timer: null };

function scheduleTarget() {
  targetLink.pending = true;
  pumpTarget();
}

async function pumpTarget() {
  if (targetLink.inFlight || !targetLink.pending) return;
  const wait = targetLink.last + 50 - performance.now();
  if (wait > 0) {
    if (!targetLink.timer) targetLink.timer = setTimeout(() => { targetLink.timer = null; pumpTarget(); }, wait);
    return;
  }
  targetLink.pending = false;
  targetLink.inFlight = true;
  targetLink.last = performance.now();
  const body = targetBody($('go-live').checked);
  const r = await post(apiPath('target'), body, { quiet: true });
  targetLink.inFlight = false;
  targetReply(r, body.go);
  pumpTarget();
}

async function sendTargetNow(go) {
  if (!scene.targetShown()) { showError('no target yet: waiting for the first telemetry'); return; }
  const r = await post(apiPath('target'), targetBody(go), { quiet: true });
  targetReply(r, go);
}

function targetReply(r, go) {
  const status = $('target-status'), detail = $('target-detail');
  const b = r.body || {};
  if (r.ok) {
    if (go) releaseSliders();
    setText(status, 'reachable');
    status.className = 'ok';
    const err = typeof b.position_error_mm === 'number' ? `IK error ${b.position_error_mm.toFixed(2)} mm` : '';
    const q = Array.isArray(b.q) ? `q = [${b.q.map((v) => v.toFixed(3)).join(', ')}]` : '';
    setText(detail, [err, q, go ? 'sent to the arm' : 'preview only'].filter(Boolean).join(' · '));
    if (Array.isArray(b.frames)) scene.setPreview(b.frames, true);
    scene.setTargetReachable(true);
    return;
  }
  let text = b.error || `HTTP ${r.status}`;
  if (b.reachable === false && !/^unreachable/.test(text)) text = `unreachable: ${text}`;
  setText(status, text);
  status.className = 'bad';
  setText(detail, b.reachable === false && Array.isArray(b.q) ? `best q = [${b.q.map((v) => v.toFixed(3)).join(', ')}]` : '');
  if (b.reachable === false) {
    scene.setTargetReachable(false);
    if (Array.isArray(b.frames)) scene.setPreview(b.frames, false);
  }
  showError(text);
}

function targetToTool(t) {
  const tool = t.frames && t.frames[arm.dof];
  if (!tool) return;
  scene.setTarget(tool.p, arm.orientation ? tool.q : null);
  showTargetInInputs();
}

function wireTarget() {
  targetInputs().forEach((el) => {
    el.addEventListener('change', () => {
      const p = targetInputs().map((e) => parseFloat(e.value));
      if (!p.every(isFinite)) { showError('the target needs three numbers (metres)'); return; }
      scene.setTarget(p, null);
      scheduleTarget();
    });
  });
  $('go').addEventListener('click', () => sendTargetNow(true));
  $('target-to-tool').addEventListener('click', () => {
    if (latest) { targetToTool(latest); scene.setPreview(null); scheduleTarget(); }
  });
  const b = $('target-mode');
  b.addEventListener('click', () => setGizmoMode(gizmoMode === 'translate' ? 'rotate' : 'translate'));
  showTargetMode();
}

let gizmoMode = 'translate';

function setGizmoMode(mode) {
  gizmoMode = mode;
  scene.setGizmoMode(mode);
  $('target-mode').textContent = mode === 'translate' ? 'Rotate' : 'Move';
}

// Rotating the target is for an arm that can choose the tool's orientation.
function showTargetMode() {
  $('target-mode').hidden = !arm.orientation;
  if (!arm.orientation && gizmoMode !== 'translate') setGizmoMode('translate');
}

// ---- buttons and playing -----------------------------------------------------------------

// Another command takes over the joints: the sliders follow its setpoints again.
function releaseSliders() { sliders.forEach((s) => { s.hold = null; }); }

function wireButtons() {
  // In a rig's view /api/stop stops every arm.
  $('stop').addEventListener('click', () => {
    releaseSliders();
    post('/api/stop', {});
  });
  $('torque-on').addEventListener('click', () => post(apiPath('torque'), { on: true }));
  $('torque-off').addEventListener('click', () => post(apiPath('torque'), { on: false }));
}

function wirePlay() {
  $('play').addEventListener('click', async () => {
    const file = $('play-file').files[0];
    const detail = $('play-detail');
    if (!file) { showError('choose a keyframe file first'); setText(detail, 'no file chosen'); return; }
    let csv;
    try { csv = await file.text(); } catch (e) { showError(`cannot read ${file.name}: ${e.message}`); return; }
    const r = await post(apiPath('play'), { name: file.name, csv });
    if (!r.ok) { setText(detail, r.body.error); return; }
    releaseSliders();
    const b = r.body;
    scene.setPath(Array.isArray(b.path) ? b.path : null);
    setText(detail, `${file.name}: ${b.keyframes} keyframes, ${fmt(b.seconds, 1)} s`);
  });
}

function showPlay(p) {
  const box = $('play-progress');
  if (!p) return;
  const T = p.seconds > 0 ? p.seconds : 0;
  const t = Math.min(Math.max(p.play_time || 0, 0), T || Infinity);
  setText(box.querySelector('.text'), `${fmt(t, 1)} / ${fmt(T, 1)} s${p.error ? ' · stopped' : p.done ? ' · done' : ''}`);
  box.title = p.error || '';
  if (p.error) setText($('play-detail'), `${p.name}: ${p.error}`);
  box.querySelector('.bar').style.width = `${T > 0 ? (100 * t) / T : p.done ? 100 : 0}%`;
  box.classList.toggle('done', !!p.done && !p.error);
  box.classList.toggle('failed', !!p.error);
}

// ---- telemetry ---------------------------------------------------------------------------

function buildLegend() {
  const box = $('legend');
  box.textContent = '';
  if (rig) {
    const who = document.createElement('span');
    who.textContent = `${arms[selected].name}:`;
    box.appendChild(who);
  }
  arm.joints.forEach((j, i) => {
    const item = document.createElement('span');
    const sw = document.createElement('span');
    sw.className = 'swatch';
    sw.style.background = JOINT_COLORS[i % JOINT_COLORS.length];
    item.append(sw, j.name || `joint ${i + 1}`);
    box.appendChild(item);
  });
  const key = document.createElement('span');
  key.textContent = 'solid: measured · dashed: setpoint';
  box.appendChild(key);
}

// Connected again shows with the first telemetry after it (onTelemetry), not the socket's open.
function onDisconnect() {
  connected = false;
  const c = $('connection');
  c.dataset.connected = 'false';
  setText(c, 'disconnected');
}

function onTelemetry(t) {
  // A rig's telemetry names its arm.
  const index = rig ? arms.findIndex((a) => a.name === t.arm) : 0;
  const a = arms[index];
  if (!a) return;
  a.latest = t;
  a.fresh = true;
  if (index === selected) latest = t;
  if (!connected) {
    connected = true;
    const c = $('connection');
    c.dataset.connected = 'true';
    setText(c, 'connected');
  }
  const now = performance.now();
  a.arrivals.push(now);
  while (a.arrivals.length && a.arrivals[0] < now - 1000) a.arrivals.shift();
  if (Array.isArray(t.measured) && Array.isArray(t.setpoints)) a.chart.push(t.time, t.measured, t.setpoints);
  if (index === selected && !targetInitialised && Array.isArray(t.frames) && t.frames.length > arm.dof) {
    targetInitialised = true;
    targetToTool(t);
  }
  // Obstacles changed (by this page or another client): drawn again.
  if (typeof t.collision_version === 'number' && t.collision_version !== a.collisionVersion) {
    a.collisionVersion = t.collision_version;
    loadCollision(index);
  }
  // Shown when it changes only, so an older server error does not hide a newer request's.
  if (t.last_error !== a.lastServerError) {
    a.lastServerError = t.last_error;
    if (t.last_error) showError(rig ? `${a.name}: ${t.last_error}` : t.last_error);
  }
}

// ---- collision geometry --------------------------------------------------------------------

/** Arm `index`'s collision geometry from the server, drawn (shown with the checkbox). */
async function loadCollision(index) {
  const a = arms[index];
  const path = rig ? `/api/arm/${encodeURIComponent(a.name)}/collision` : '/api/collision';
  try {
    scene.setCollision(await getJSON(path), index);
  } catch (e) {
    showError(`cannot read the collision geometry (${path}): ${e.message}`);
  }
}

function wireCollision() {
  const box = $('show-collision');
  box.checked = false;
  box.addEventListener('change', () => scene.showCollision(box.checked));
}

// ---- the rig's arms ----------------------------------------------------------------------

function showArmName() {
  const text = rig
    ? `rig ${rig.name} · driving ${arms[selected].name} (${arm.name}, ${arm.dof} joints)`
    : `${arm.name} · ${arm.dof} joints`;
  setText($('arm-name'), text);
}

/** A rig's list: one row per arm with its telemetry, and the choice of the arm to drive. */
function buildRig() {
  if (!rig) return;
  $('rig-section').hidden = false;
  setText($('rig-name'), `${rig.name} · ${arms.length} arms, world frame`);
  setText($('target-frame'), 'm, world frame');
  const box = $('arms');
  box.textContent = '';
  arms.forEach((a, i) => {
    const row = document.createElement('label');
    row.className = 'arm-row';
    row.id = `arm-row-${a.name}`;
    const base = a.base && Array.isArray(a.base.p) ? a.base.p.map((x) => x.toFixed(2)).join(', ') : '—';
    row.innerHTML = `
      <input type="radio" name="arm-pick" id="arm-pick-${a.name}">
      <span class="arm-title"><b class="n"></b> <span class="model"></span></span>
      <span class="arm-state" id="arm-${a.name}-state">—</span>
      <span class="arm-nums">tool <span id="arm-${a.name}-tool">—</span> m · error <span id="arm-${a.name}-error">—</span> mm
        · loop max <span id="arm-${a.name}-loop">—</span> µs · bus errors <span id="arm-${a.name}-bus">—</span>
        · queue <span id="arm-${a.name}-queue">—</span></span>
      <span class="arm-base">base at ${base}</span>`;
    row.querySelector('.n').textContent = a.name;
    row.querySelector('.model').textContent = `${a.arm.name}, ${a.arm.dof} joints`;
    const pick = row.querySelector('input');
    pick.checked = i === selected;
    pick.addEventListener('change', () => { if (pick.checked) select(i); });
    box.appendChild(row);
    a.row = {
      state: row.querySelector(`#arm-${a.name}-state`),
      tool: row.querySelector(`#arm-${a.name}-tool`),
      error: row.querySelector(`#arm-${a.name}-error`),
      loop: row.querySelector(`#arm-${a.name}-loop`),
      bus: row.querySelector(`#arm-${a.name}-bus`),
      queue: row.querySelector(`#arm-${a.name}-queue`),
    };
  });
}

function showArmRow(a) {
  const t = a.latest;
  if (!a.row || !t) return;
  setText(a.row.state, `${t.state}${t.torque === false && t.state !== 'TorqueOff' ? ' · torque off' : ''}`);
  setText(a.row.tool, Array.isArray(t.tool) ? t.tool.map((x) => fmt(x)).join(', ') : '—');
  setText(a.row.error, fmt(t.tool_error_mm, 1));
  setText(a.row.loop, fmt(t.loop && t.loop.max_us, 0));
  setText(a.row.bus, `${(t.bus_errors && t.bus_errors.total) ?? '—'}`);
  setText(a.row.queue, `${t.queue ? t.queue.queued : '—'} / ${t.queue ? t.queue.capacity : '—'}`);
}

/** The controls drive arm `index` from now on. */
function select(index) {
  if (index === selected || !arms[index]) return;
  targetLink.pending = false;
  selected = index;
  arm = arms[index].arm;
  latest = arms[index].latest;
  chart = arms[index].chart;
  chart.dirty = true;
  arms[index].fresh = true;
  showArmName();
  buildJoints();
  buildGripper();
  buildLegend();
  scene.select(index);
  scene.setPreview(null);
  scene.setPath(null);
  showTargetMode();
  for (const id of ['target-status', 'target-detail', 'play-detail']) setText($(id), id === 'target-status' ? '—' : '');
  $('target-status').className = '';
  // The target starts at this arm's tool.
  targetInitialised = false;
  if (latest && Array.isArray(latest.frames) && latest.frames.length > arm.dof) {
    targetInitialised = true;
    targetToTool(latest);
  }
  const pick = $(`arm-pick-${arms[index].name}`);
  if (pick) pick.checked = true;
}

function showNumbers(t) {
  setText($('state'), `${t.state}${t.torque === false && t.state !== 'TorqueOff' ? ' · torque off' : ''}`);
  setText($('tool-error'), `${fmt(t.tool_error_mm, 1)} mm`);
  const l = t.loop || {};
  setText($('loop-time'), `${fmt(l.mean_us, 0)} / ${fmt(l.max_us, 0)} µs`);
  setText($('overruns'), `${l.overruns ?? '—'}`);
  const b = t.bus_errors || {};
  const parts = Object.entries(b).filter(([k, v]) => k !== 'total' && v).map(([k, v]) => `${k} ${v}`);
  setText($('bus-errors'), `${b.total ?? 0}${parts.length ? ` (${parts.join(', ')})` : ''}`);
  const q = t.queue || {};
  setText($('queue'), `${q.queued ?? '—'} / ${q.capacity ?? arm.queue_capacity ?? '—'}`);
  setText($('rate'), `${fmt(t.rate_hz, 0)} Hz (${arms[selected].arrivals.length}/s here)`);
  const g = t.gripper;
  const gtext = g ? `${fmt(g.percent, 0)} % (setpoint ${fmt(g.setpoint_percent, 0)} %)` : 'none';
  setText($('gripper-telemetry'), gtext);
  if (arm.gripper) {
    if (!gripperDragging) {
      setText($('gripper-state'), gtext);
      if (g && typeof g.setpoint_percent === 'number') $('gripper').value = String(g.setpoint_percent);
    }
  }
  showPlay(t.play);
}

function frame() {
  arms.forEach((a, i) => {
    if (!a.fresh || !a.latest) return;
    a.fresh = false;
    const t = a.latest;
    if (Array.isArray(t.frames)) scene.setFrames(t.frames, i);
    scene.setToolSetpoint(Array.isArray(t.tool_setpoint) ? t.tool_setpoint : null, i);
    showArmRow(a);
    if (i === selected) {
      followSetpoints(t);
      showNumbers(t);
    }
  });
  chart.draw();
  scene.render();
  requestAnimationFrame(frame);
}

start();
