// End-to-end browser test of `armctl view` (contract: the server's JSON API and the page's ids).
//
// Starts `$ARMCTL view --sim --listen 127.0.0.1:0`, opens its page in headless Chromium (Debian's,
// driven by playwright-core) and checks, each as a named step printing `ok - name` or
// `not ok - name: reason`:
//   a. the page loads, the websocket connects, the 3D canvas is drawn (not blank);
//   b. a joint slider moves the simulated arm;
//   c. dragging the target gizmo with "go live" brings the tool to the target;
//   d. the stop button stops a playing keyframe file;
//   e. the API refuses bad inputs (4xx with {"error": ...}) and nothing moves;
//   g. only the person who started it drives it (issue 27): the token printed in the URL leaves the
//      address bar, the API refuses requests without it, with a wrong one, from another Origin or
//      Host, and non-JSON POSTs, and a hostile page on another origin cannot move the arm;
//   f. cost: websocket messages per second and the server's CPU, written to cost.json;
// then that the page threw no uncaught error and that SIGINT ends the server.
// Exit code 1 when any step failed. The server and the browser are always ended; the whole run
// is bounded by OVERALL_MS.
//
// Environment: ARMCTL (the binary, required), VIEW_E2E_OUT (folder for screenshots and cost.json,
// default ./out), CHROMIUM (default /usr/bin/chromium).
// Run by host/tests/view_browser.rs; by hand: ARMCTL=target/debug/armctl node host/tests/view/e2e.mjs

import { spawn, execFileSync } from 'node:child_process';
import { randomBytes } from 'node:crypto';
import { createServer, request as httpRequest } from 'node:http';
import { mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';
import {
  CHROMIUM_ARGS, check, decodePng, differingPixels, distance, fmt, maxAbsDiff, note, sleep, until,
} from './harness.mjs';

const OVERALL_MS = 180_000;
const ARMCTL = process.env.ARMCTL;
const OUT = process.env.VIEW_E2E_OUT || 'out';
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';

if (!ARMCTL) {
  console.log('not ok - setup: set ARMCTL to the armctl binary');
  process.exit(1);
}
mkdirSync(OUT, { recursive: true });

// ---------------------------------------------------------------------------------------------
// Steps: each prints one TAP-like line; a failure does not stop the later steps.

const results = [];
let shots = 0;
let page = null;

async function step(name, body) {
  try {
    await body();
    results.push({ name, ok: true });
    console.log(`ok - ${name}`);
  } catch (error) {
    const reason = String(error?.message ?? error).split('\n')[0];
    results.push({ name, ok: false, reason });
    console.log(`not ok - ${name}: ${reason}`);
    if (page && !page.isClosed()) {
      await screenshot(`failed-${name.replace(/[^a-z0-9]+/gi, '-').slice(0, 40)}`).catch(() => {});
    }
  }
}

/// Drags with the left button from `from` (page CSS pixels) by (dx, dy), in small steps as a hand does.
async function dragBy(from, dx, dy, steps = 12) {
  await page.mouse.move(from.x, from.y);
  await sleep(100); // hover first: the gizmo picks its handle on pointer moves
  await page.mouse.down();
  for (let i = 1; i <= steps; i++) {
    await page.mouse.move(from.x + (dx * i) / steps, from.y + (dy * i) / steps);
    await sleep(30);
  }
  await page.mouse.up();
}

async function screenshot(name) {
  shots += 1;
  const path = join(OUT, `${String(shots).padStart(2, '0')}-${name}.png`);
  await page.screenshot({ path, fullPage: true, timeout: 15_000 });
  note(`screenshot ${path}`);
  return path;
}

// ---------------------------------------------------------------------------------------------
// The server.

let server = null;
let serverExit = null; // {code, signal} once it exited
let serverStderr = '';
let base = null;
let token = null; // the first line's ?token=, which every API request carries

function startServer() {
  server = spawn(ARMCTL, ['view', '--sim', '--listen', '127.0.0.1:0'], { stdio: ['ignore', 'pipe', 'pipe'] });
  server.stderr.setEncoding('utf8');
  server.stderr.on('data', (d) => {
    serverStderr += d;
  });
  const exited = new Promise((resolve) => {
    server.on('exit', (code, signal) => {
      serverExit = { code, signal };
      resolve(serverExit);
    });
    server.on('error', (error) => {
      serverExit = { code: null, signal: null, error: error.message };
      resolve(serverExit);
    });
  });
  const firstLine = new Promise((resolve, reject) => {
    let stdout = '';
    server.stdout.setEncoding('utf8');
    server.stdout.on('data', (d) => {
      stdout += d;
      const newline = stdout.indexOf('\n');
      if (newline >= 0) resolve(stdout.slice(0, newline).trim());
    });
    exited.then((e) => reject(new Error(`armctl view exited before printing its URL (${JSON.stringify(e)})`)));
    setTimeout(() => reject(new Error('armctl view printed no URL within 60 s')), 60_000);
  });
  return { exited, firstLine };
}

async function stopServer(signal = 'SIGINT', ms = 5000) {
  if (!server || serverExit) return serverExit;
  server.kill(signal);
  const deadline = Date.now() + ms;
  while (!serverExit && Date.now() < deadline) await sleep(50);
  if (!serverExit) {
    server.kill('SIGKILL');
    while (!serverExit) await sleep(50);
    return null;
  }
  return serverExit;
}

/// One request to the server's API from node, with the token: {status, type, text, json}.
async function api(method, path, body, { raw } = {}) {
  const init = { method, signal: AbortSignal.timeout(5000), headers: { authorization: `Bearer ${token}` } };
  if (raw !== undefined || body !== undefined) {
    init.headers['content-type'] = 'application/json';
    init.body = raw !== undefined ? raw : JSON.stringify(body);
  }
  const response = await fetch(new URL(path, base), init);
  const text = await response.text();
  let json = null;
  try {
    json = JSON.parse(text);
  } catch {
    // Left null: the callers say what they expected.
  }
  return { status: response.status, type: response.headers.get('content-type') ?? '', text, json };
}

/// One request with exactly the headers given (node:http sets Host and Origin as told, which fetch
/// may not): {status, text, json}; with `upgrade`, a websocket handshake: {status: 101} if it
/// was accepted (the socket is then closed).
function rawRequest(method, path, { headers = {}, body, upgrade = false } = {}) {
  return new Promise((resolve, reject) => {
    const all = { ...headers };
    if (upgrade) {
      Object.assign(all, {
        connection: 'Upgrade',
        upgrade: 'websocket',
        'sec-websocket-version': '13',
        'sec-websocket-key': randomBytes(16).toString('base64'),
      });
    }
    if (body !== undefined) all['content-length'] = Buffer.byteLength(body);
    const req = httpRequest({
      host: base.hostname, port: base.port, method, path, headers: all, agent: false, timeout: 5000,
    });
    req.on('upgrade', (response, socket) => {
      socket.destroy();
      resolve({ status: response.statusCode, text: '', json: null });
    });
    req.on('response', (response) => {
      let text = '';
      response.setEncoding('utf8');
      response.on('data', (d) => {
        text += d;
      });
      response.on('end', () => {
        let json = null;
        try {
          json = JSON.parse(text);
        } catch {
          // Left null: the callers say what they expected.
        }
        resolve({ status: response.statusCode, text, json });
      });
    });
    req.on('timeout', () => req.destroy(new Error(`${method} ${path}: no answer within 5 s`)));
    req.on('error', reject);
    req.end(body);
  });
}

async function status() {
  const r = await api('GET', '/api/status');
  check(r.status === 200 && r.json, `GET /api/status answered ${r.status}: ${r.text.slice(0, 200)}`);
  return r.json;
}

// ---------------------------------------------------------------------------------------------
// The run.

let browser = null;
const tempDir = mkdtempSync(join(tmpdir(), 'armctl-view-e2e-'));
const pageErrors = [];
const consoleErrors = [];

async function cleanup() {
  if (browser) await Promise.race([browser.close().catch(() => {}), sleep(10_000)]);
  browser = null;
  await stopServer('SIGINT', 3000);
  rmSync(tempDir, { recursive: true, force: true });
}

const watchdog = setTimeout(async () => {
  console.log(`not ok - overall time limit: the run took longer than ${OVERALL_MS / 1000} s`);
  await Promise.race([cleanup(), sleep(15_000)]);
  if (server && !serverExit) server.kill('SIGKILL');
  process.exit(1);
}, OVERALL_MS);

async function main() {
  const started = startServer();
  let url;
  await step('armctl view --sim --listen 127.0.0.1:0 starts and prints its URL first', async () => {
    url = await started.firstLine;
    note(`URL ${url}`);
    base = new URL(url);
    token = base.searchParams.get('token');
    check(base.protocol === 'http:' && base.hostname === '127.0.0.1' && Number(base.port) > 0 && base.pathname === '/',
      `the first stdout line is not http://127.0.0.1:PORT/?token=TOKEN: ${JSON.stringify(url)}`);
    check(token && token.length >= 32 && /^[A-Za-z0-9._~-]+$/.test(token),
      `the URL's token is missing, shorter than 32 characters or not URL-safe: ${JSON.stringify(token)}`);
  });
  if (!base) return;

  const arm = (await api('GET', '/api/arm')).json;
  check(arm && Array.isArray(arm.joints), 'GET /api/arm gave no joints');
  note(`arm ${arm.name}: ${arm.dof} joints, limits ${arm.joints.map((j) => `[${j.lower}, ${j.upper}]`).join(' ')}`);

  await step('GET /api/arm and GET /api/status have the fields of the spec', async () => {
    const problems = [];
    const need = (ok, what) => ok || problems.push(what);
    const isNum = (x) => typeof x === 'number' && Number.isFinite(x);
    const isVec = (v, n) => Array.isArray(v) && v.length === n && v.every(isNum);
    need(typeof arm.name === 'string' && arm.dof === arm.joints.length, 'arm: name, dof = joints.length');
    for (const [j, joint] of arm.joints.entries()) {
      need(typeof joint.name === 'string' && ['revolute', 'prismatic', 'continuous'].includes(joint.kind) &&
        isNum(joint.lower) && isNum(joint.upper) && joint.lower < joint.upper && isVec(joint.axis, 3),
      `arm.joints[${j}]: name, kind, lower < upper, axis`);
    }
    need(typeof arm.orientation === 'boolean', 'arm.orientation');
    need(arm.gripper === null || (isNum(arm.gripper.min_percent) && isNum(arm.gripper.max_percent)), 'arm.gripper');
    need(isNum(arm.reach) && arm.reach > 0, 'arm.reach');
    need(Number.isInteger(arm.queue_capacity) && arm.queue_capacity > 0, 'arm.queue_capacity');
    need(Array.isArray(arm.meshes), 'arm.meshes');
    const a = await status();
    await sleep(200);
    const s = await status();
    need(Number.isInteger(a.seq) && s.seq > a.seq, `seq increases (${a.seq} then ${s.seq})`);
    need(isNum(s.time) && s.time > a.time, 'time increases');
    need(typeof s.state === 'string' && typeof s.torque === 'boolean', 'state, torque');
    need(isVec(s.measured, arm.dof) && isVec(s.setpoints, arm.dof), 'measured, setpoints: one per joint');
    const framesOk = Array.isArray(s.frames) && s.frames.length === arm.dof + 1 &&
      s.frames.every((f) => isVec(f.p, 3) && isVec(f.q, 4) && Math.abs(Math.hypot(...f.q) - 1) < 1e-6);
    need(framesOk, 'frames: dof + 1 frames {p, q} with unit quaternions');
    need(isVec(s.tool, 3) && framesOk && distance(s.tool, s.frames[arm.dof].p) < 1e-9, 'tool = frames[dof].p');
    need(isVec(s.tool_setpoint, 3) && isNum(s.tool_error_mm), 'tool_setpoint, tool_error_mm');
    need(s.loop && ['mean_us', 'max_us', 'overruns'].every((k) => isNum(s.loop[k])),
      `loop {mean_us, max_us, overruns}: got ${JSON.stringify(s.loop)}`);
    need(s.bus_errors && isNum(s.bus_errors.total), 'bus_errors.total');
    need(s.queue && isNum(s.queue.queued) && isNum(s.queue.free) && s.queue.capacity === arm.queue_capacity,
      'queue {queued, free, capacity = arm.queue_capacity}');
    need(arm.gripper ? s.gripper && isNum(s.gripper.percent) && isNum(s.gripper.setpoint_percent) : s.gripper === null,
      'gripper {percent, setpoint_percent} (null without one)');
    need(['play', 'target', 'last_error'].every((k) => k in s), 'play, target, last_error present');
    need(isNum(s.rate_hz), 'rate_hz');
    check(problems.length === 0, `missing or wrong: ${problems.join('; ')}`);
  });

  browser = await chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, headless: true, timeout: 60_000 });
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 }, deviceScaleFactor: 1 });
  page = await context.newPage();
  page.setDefaultTimeout(15_000);
  page.on('pageerror', (error) => pageErrors.push(String(error?.message ?? error).split('\n')[0]));
  page.on('console', (message) => {
    if (message.type() === 'error') consoleErrors.push(message.text().split('\n')[0]);
  });

  // a. -----------------------------------------------------------------------------------------
  await step('the page loads and its websocket connects (#connection data-connected="true")', async () => {
    const response = await page.goto(url, { waitUntil: 'load', timeout: 30_000 });
    check(response && response.status() === 200, `GET / answered ${response?.status()}`);
    await page.waitForSelector('#connection[data-connected="true"]', { timeout: 15_000 }).catch(async () => {
      const text = await page.locator('#connection').textContent({ timeout: 1000 }).catch(() => '(no #connection)');
      throw new Error(`#connection never got data-connected="true" within 15 s; its text: ${JSON.stringify(text)}`);
    });
  });

  await step('the 3D view (canvas#view3d) is drawn, not blank', async () => {
    const canvas = page.locator('canvas#view3d');
    await canvas.waitFor({ state: 'visible', timeout: 10_000 });
    // Let the meshes load and a few frames render (software WebGL is slow).
    await page.evaluate(() => new Promise((resolve) => {
      let frames = 0;
      const tick = () => (++frames >= 10 ? resolve() : requestAnimationFrame(tick));
      requestAnimationFrame(tick);
    }));
    await sleep(1500);
    await screenshot('loaded');
    const png = await canvas.screenshot({ timeout: 15_000 });
    shots += 1;
    const canvasPath = join(OUT, `${String(shots).padStart(2, '0')}-canvas.png`);
    writeFileSync(canvasPath, png);
    note(`screenshot ${canvasPath}`);
    const image = decodePng(png);
    const s = differingPixels(image);
    const share = s.differing / s.total;
    note(`canvas ${image.width}x${image.height}: ${s.differing} of ${s.total} pixels (${(100 * share).toFixed(1)} %) ` +
      `differ from the corner colour rgb(${s.background.join(',')}); ${s.colours} colours`);
    check(image.width >= 200 && image.height >= 150, `the canvas is only ${image.width}x${image.height}`);
    check(share >= 0.01 && s.colours >= 4,
      `the canvas looks blank: ${(100 * share).toFixed(2)} % of pixels differ from the background, ${s.colours} colours`);
  });

  await step('the token is out of the address bar once the page loaded, and the page still works', async () => {
    const shown = page.url();
    note(`address bar: ${shown}`);
    check(!shown.includes(token) && !new URL(shown).searchParams.has('token'),
      `page.url() still has the token: ${shown}`);
    check(new URL(shown).origin === base.origin && new URL(shown).pathname === '/', `page.url() is ${shown}`);
    check(await page.locator('#connection[data-connected="true"]').count() === 1,
      'the page lost its websocket once the token left the address bar');
  });

  await step('#show-collision draws the link capsules and the obstacles; an obstacle added by the API is drawn', async () => {
    const drawn = () => page.evaluate(() => window.armView.drawnCollision()[0]);
    const geometry = (await api('GET', '/api/collision')).json;
    check(geometry && Array.isArray(geometry.bodies) && geometry.bodies.length > 0, `GET /api/collision: ${JSON.stringify(geometry)}`);
    const hidden = await until(5000, 'the page did not load the collision geometry', async () => {
      const d = await drawn();
      return d && d.bodies > 0 ? d : { done: false, d };
    }, { every: 100 });
    check(!hidden.shown, 'the collision geometry shows before the checkbox is ticked');
    // Each body a tube and one or two balls.
    check(hidden.bodies >= 2 * geometry.bodies.length, `${hidden.bodies} meshes for ${geometry.bodies.length} bodies`);
    const canvas = page.locator('canvas#view3d');
    const before = decodePng(await canvas.screenshot({ timeout: 15_000 }));
    await page.locator('#show-collision').check();
    await sleep(300);
    const after = decodePng(await canvas.screenshot({ timeout: 15_000 }));
    const shown = await drawn();
    check(shown.shown && shown.obstacles === geometry.obstacles.length, `after the checkbox: ${JSON.stringify(shown)}`);
    let changed = 0;
    for (let i = 0; i < before.data.length; i += 4) if (before.data[i] !== after.data[i] || before.data[i + 1] !== after.data[i + 1]) changed++;
    note(`ticking #show-collision changed ${changed} pixels`);
    check(changed > 1000, `ticking #show-collision changed only ${changed} pixels`);
    await screenshot('collision');
    // The firmware takes new geometry with the arm, only with the torque off.
    check((await api('POST', '/api/torque', { on: false })).status === 200, 'torque off');
    const added = await api('POST', '/api/obstacles', { add: [{ shape: 'box', name: 'crate', centre: [0.25, 0.1, 0.05], size: [0.06, 0.06, 0.1] }] });
    check(added.status === 200, `POST /api/obstacles: ${added.status} ${added.text}`);
    await until(5000, 'the page did not draw the added box', async () => {
      const d = await drawn();
      return d.names.includes('crate') && d.obstacles === geometry.obstacles.length + 1 ? d : { done: false, d };
    }, { every: 100 });
    check((await api('POST', '/api/obstacles', { remove: ['crate'] })).status === 200, 'removing the box');
    await until(5000, 'the page still draws the removed box', async () => {
      const d = await drawn();
      return !d.names.includes('crate') ? d : { done: false, d };
    }, { every: 100 });
    await page.locator('#show-collision').uncheck();
  });

  // b. -----------------------------------------------------------------------------------------
  await step('moving slider #joint-1 moves the simulated arm (measured[1] follows)', async () => {
    const slider = page.locator('#joint-1');
    const attrs = await slider.evaluate((el) => ({ type: el.type, min: Number(el.min), max: Number(el.max), step: el.step }));
    check(attrs.type === 'range', `#joint-1 is an input of type ${attrs.type}, not range`);
    const limits = arm.joints[1];
    check(Math.abs(attrs.min - limits.lower) < 1e-3 && Math.abs(attrs.max - limits.upper) < 1e-3,
      `#joint-1's min/max ${attrs.min}/${attrs.max} are not the joint's limits ${limits.lower}/${limits.upper}`);
    const before = await status();
    let goal = 0.5;
    if (goal < attrs.min + 0.05 || goal > attrs.max - 0.05) goal = Number(((attrs.min + attrs.max) / 2).toFixed(3));
    if (Math.abs(before.measured[1] - goal) < 0.2) goal = Number((goal - 0.4).toFixed(3));
    note(`joint 1 at ${fmt(before.measured[1])} rad; slider to ${goal} (limits ${attrs.min}..${attrs.max})`);

    await slider.evaluate((el) => {
      window.__sliderEvents = { input: 0, change: 0 };
      el.addEventListener('input', () => window.__sliderEvents.input++);
      el.addEventListener('change', () => window.__sliderEvents.change++);
    });
    const posted = page.waitForResponse(
      (r) => r.url().endsWith('/api/joints') && r.request().method() === 'POST', { timeout: 5000 });
    posted.catch(() => {});
    await slider.fill(String(goal));
    const events = await page.evaluate(() => window.__sliderEvents);
    if (events.change === 0) {
      note(`locator.fill dispatched ${JSON.stringify(events)}; dispatching input and change by hand`);
      await slider.evaluate((el) => {
        el.dispatchEvent(new Event('input', { bubbles: true }));
        el.dispatchEvent(new Event('change', { bubbles: true }));
      });
    } else {
      note(`locator.fill dispatched ${JSON.stringify(events)}`);
    }
    const response = await posted.catch(() => null);
    check(response, 'the page sent no POST /api/joints within 5 s of the slider\'s change');
    note(`page sent POST /api/joints ${response.request().postData()} -> ${response.status()} ${await response.text()}`);
    check(response.status() === 200, `POST /api/joints answered ${response.status()}`);
    const t0 = Date.now();
    const last = await until(10_000, `measured[1] did not reach ${goal} ± 0.01 rad`, async () => {
      const s = await status();
      return Math.abs(s.measured[1] - goal) <= 0.01 ? s : { done: false, measured: s.measured, state: s.state };
    }, { every: 100 });
    note(`measured[1] = ${fmt(last.measured[1])} rad after ${((Date.now() - t0) / 1000).toFixed(1)} s`);
    const shown = await until(3000, `#joint-1-measured did not show ${goal} ± 0.01`, async () => {
      const text = await page.locator('#joint-1-measured').textContent();
      return Math.abs(parseFloat(text) - goal) <= 0.01 ? text : { done: false, text };
    }, { every: 100 });
    note(`#joint-1-measured shows ${JSON.stringify(shown)}`);
  });

  // c. -----------------------------------------------------------------------------------------
  await step('dragging the target gizmo with #go-live moves the tool to the target (within 1 mm)', async () => {
    await until(5000, 'the arm did not come to rest', async () => {
      const s = await status();
      return s.state === 'Idle' ? s : { done: false, state: s.state };
    }, { every: 100 });
    await page.locator('#go-live').check();
    check(await page.locator('#go-live').isChecked(), '#go-live is not checked after check()');
    const targetPosts = [];
    const onResponse = async (r) => {
      if (r.url().endsWith('/api/target') && r.request().method() === 'POST') {
        targetPosts.push({ request: r.request().postData(), status: r.status(), body: await r.text().catch(() => '') });
      }
    };
    page.on('response', onResponse);
    try {
      const drags = [[40, 0], [-40, 0], [0, -40], [0, 40], [20, 0], [-20, 0], [0, -20], [0, 20]];
      let reached = null;
      for (const [dx, dy] of drags) {
        const from = await page.evaluate(() => window.armView.targetScreen());
        const target0 = await page.evaluate(() => window.armView.target());
        check(Number.isFinite(from?.x) && Number.isFinite(from?.y), `armView.targetScreen() gave ${JSON.stringify(from)}`);
        const posts0 = targetPosts.length;
        await dragBy(from, dx, dy);
        await sleep(700); // the last POST /api/target of the drag
        const target1 = await page.evaluate(() => window.armView.target());
        const moved = distance(target0, target1);
        const text = (await page.locator('#target-status').textContent()) ?? '';
        const last = targetPosts[targetPosts.length - 1];
        note(`drag (${dx}, ${dy}) px from (${fmt(from.x, 1)}, ${fmt(from.y, 1)}): target ${fmt(target0)} -> ` +
          `${fmt(target1)} (${(moved * 1000).toFixed(1)} mm), ${targetPosts.length - posts0} POST /api/target, ` +
          `#target-status ${JSON.stringify(text)}` + (last ? `; last: ${last.request} -> ${last.status}` : ''));
        check(moved > 0.002, `the drag did not move the target (armView.target() ${fmt(target0)} -> ${fmt(target1)}): ` +
          'targetScreen() is not on the gizmo, or the gizmo does not follow the mouse');
        check(targetPosts.length > posts0, 'the drag moved the target but the page sent no POST /api/target');
        let sentGo = false;
        try {
          sentGo = JSON.parse(last.request).go === true;
        } catch {
          // Not JSON: reported below.
        }
        check(sentGo, `with #go-live checked, the page sent ${last.request} (no "go": true)`);
        if (last.status === 200 && !text.startsWith('unreachable')) {
          reached = target1;
          break;
        }
        note('unreachable: dragging back, then a smaller or another direction');
        const back = await page.evaluate(() => window.armView.targetScreen());
        await dragBy(back, -dx, -dy);
        await sleep(700);
      }
      check(reached, 'every drag led to an unreachable target');
      await screenshot('after-drag');
      const t0 = Date.now();
      const s = await until(10_000, 'the tool did not reach armView.target() within 1 mm', async () => {
        const st = await status();
        const target = await page.evaluate(() => window.armView.target());
        const d = distance(st.tool, target);
        return d <= 0.001 ? { st, d } : { done: false, tool: st.tool, target, mm: d * 1000, state: st.state };
      }, { every: 100 });
      note(`tool ${fmt(s.st.tool)} is ${(s.d * 1000).toFixed(2)} mm from the target after ` +
        `${((Date.now() - t0) / 1000).toFixed(1)} s (state ${s.st.state})`);
      await sleep(500);
      await screenshot('tool-at-target');
    } finally {
      page.off('response', onResponse);
    }
  });

  // d. -----------------------------------------------------------------------------------------
  await step('#stop stops a playing keyframe file (Idle within 3 s, joints still, play time well short)', async () => {
    await until(5000, 'the arm did not come to rest', async () => {
      const s = await status();
      return s.state === 'Idle' ? s : { done: false, state: s.state };
    }, { every: 100 });
    // Joint 1 to 0 first, the others where they are, so the wave starts where the arm stands.
    const here = (await status()).measured;
    const clamp = (x, j) => Math.min(Math.max(x, arm.joints[j].lower + 0.01), arm.joints[j].upper - 0.01);
    const start = here.map((x, j) => Number(clamp(j === 0 ? 0 : x, j).toFixed(4)));
    const home = await api('POST', '/api/joints', { q: start });
    check(home.status === 200, `POST /api/joints ${JSON.stringify({ q: start })} answered ${home.status} ${home.text}`);
    await until(8000, `the arm did not reach ${fmt(start)}`, async () => {
      const s = await status();
      return s.state === 'Idle' && maxAbsDiff(s.measured, start) < 0.01 ? s : { done: false, state: s.state, measured: s.measured };
    }, { every: 100 });

    // A slow wave of joint 1: one period over 7.5 s after 0.5 s at the start, ±0.8 rad (within its limits).
    const amplitude = Math.min(0.8, 0.9 * -arm.joints[0].lower, 0.9 * arm.joints[0].upper);
    const header = ['t', ...arm.joints.map((_, j) => `q${j + 1}`)].join(',');
    const lines = [header];
    for (let i = 0; i <= 75; i++) {
      const t = 0.5 + 0.1 * i;
      const q = start.slice();
      q[0] = amplitude * Math.sin((2 * Math.PI * (t - 0.5)) / 7.5);
      lines.push([t.toFixed(2), ...q.map((x) => x.toFixed(4))].join(','));
    }
    const seconds = 8.0;
    const file = join(tempDir, 'wave.csv');
    writeFileSync(file, `${lines.join('\n')}\n`);
    note(`wave.csv: 76 keyframes over ${seconds} s, joint 1 within ±${amplitude.toFixed(3)} rad`);

    await page.locator('#play-file').setInputFiles(file);
    const played = page.waitForResponse((r) => r.url().endsWith('/api/play') && r.request().method() === 'POST',
      { timeout: 5000 });
    played.catch(() => {});
    await page.locator('#play').click();
    const response = await played.catch(() => null);
    check(response, 'clicking #play sent no POST /api/play within 5 s');
    const body = await response.text();
    note(`POST /api/play -> ${response.status()} ${body.slice(0, 160)}${body.length > 160 ? '...' : ''}`);
    check(response.status() === 200, `POST /api/play answered ${response.status()}: ${body}`);
    const plan = JSON.parse(body);
    check(plan.keyframes === 76 && Math.abs(plan.seconds - seconds) < 1e-6,
      `POST /api/play planned ${plan.keyframes} keyframes over ${plan.seconds} s, expected 76 over ${seconds}`);

    const moving = await until(8000, 'the file did not play (state Moving, play_time > 0.5 s)', async () => {
      const s = await status();
      return s.state === 'Moving' && s.play && s.play.play_time > 0.5 ? s : { done: false, state: s.state, play: s.play };
    }, { every: 50 });
    await screenshot('playing');
    const stopped = page.waitForResponse((r) => r.url().endsWith('/api/stop') && r.request().method() === 'POST',
      { timeout: 3000 });
    stopped.catch(() => {});
    const clicked = Date.now();
    await page.locator('#stop').click();
    note(`playing at ${fmt(moving.play.play_time, 2)} s of ${moving.play.seconds} s (joint 1 ${fmt(moving.measured[0])}); clicked #stop`);
    const stopResponse = await stopped.catch(() => null);
    check(stopResponse, 'clicking #stop sent no POST /api/stop within 3 s');
    check(stopResponse.status() === 200, `POST /api/stop answered ${stopResponse.status()}`);
    const idle = await until(3000, 'the state did not become Idle', async () => {
      const s = await status();
      return s.state === 'Idle' ? s : { done: false, state: s.state, seq: s.seq, time: s.time, setpoints: s.setpoints, queue: s.queue, play: s.play };
    }, { every: 50 });
    note(`Idle ${((Date.now() - clicked) / 1000).toFixed(2)} s after the click; play ${JSON.stringify(idle.play)}`);
    await sleep(500);
    const a = await status();
    await sleep(1000);
    const b = await status();
    const drift = maxAbsDiff(a.measured, b.measured);
    note(`over 1 s after stopping: joints moved ${fmt(drift, 5)} rad at most; state ${b.state}; ` +
      `play_time ${b.play ? fmt(b.play.play_time, 2) : '(no play)'}`);
    check(b.state === 'Idle', `the state went back to ${b.state} after stopping`);
    check(drift < 0.001, `the joints kept moving after the stop: ${fmt(a.measured)} -> ${fmt(b.measured)}`);
    check(maxAbsDiff(a.setpoints, b.setpoints) < 1e-6, `the setpoints kept changing: ${fmt(a.setpoints)} -> ${fmt(b.setpoints)}`);
    if (b.play) {
      check(b.play.play_time < seconds / 2,
        `play_time ${b.play.play_time} s is not well below the file's ${seconds} s: the file went on playing`);
      check(b.play.play_time - (a.play?.play_time ?? b.play.play_time) < 0.05, 'play_time still advances after the stop');
    }
    await screenshot('stopped');
  });

  // e. -----------------------------------------------------------------------------------------
  const joints = arm.joints.length;
  const zeros = Array(joints).fill(0);
  const badCsv = `${['t', ...arm.joints.map((_, j) => `q${j + 1}`)].join(',')}\n0.5,${zeros.join(',')}\n1,${zeros
    .map((_, j) => (j === 2 ? 'x' : '0'))
    .join(',')}\n`;
  const beyond = zeros.slice();
  beyond[0] = arm.joints[0].upper + 0.5;
  const cases = [
    ['bad JSON body', '/api/joints', { raw: '{"q": [0, 0,' }, 400],
    ['NaN (invalid JSON)', '/api/joints', { raw: `{"q": [${['NaN', ...zeros.slice(1)].join(', ')}]}` }, 400],
    ['a number too large for a float (1e999)', '/api/joints', { raw: `{"q": [${['1e999', ...zeros.slice(1)].join(', ')}]}` }, 400],
    ['a string where a number goes', '/api/joints', { body: { q: ['0.1', ...zeros.slice(1)] } }, 400],
    ['a missing field', '/api/joints', { body: { speed: 0.5 } }, 400],
    [`the wrong number of joints (${joints - 2} for ${joints})`, '/api/joints', { body: { q: zeros.slice(2) } }, 400],
    [`joint 1 beyond its limit (${beyond[0].toFixed(3)} > ${arm.joints[0].upper})`, '/api/joints', { body: { q: beyond } }, 400],
    ['a target far outside reach with go:true', '/api/target', { body: { position: [5, 0, 0], go: true } }, 422],
    ['torque with a non-boolean', '/api/torque', { body: { on: 'yes' } }, 400],
    ['play with a CSV with a bad line (line 3)', '/api/play', { body: { name: 'bad.csv', csv: badCsv } }, 400, /line 3/],
  ];
  if (arm.gripper) cases.push(['gripper beyond 100 %', '/api/gripper', { body: { percent: 150 } }, 400]);
  for (const [what, path, { raw, body }, expected, mention] of cases) {
    await step(`the API refuses ${what}: ${path} -> ${expected} {"error"}, nothing moves`, async () => {
      const before = await until(5000, 'the arm was not at rest before the request', async () => {
        const s = await status();
        return s.state === 'Idle' ? s : { done: false, state: s.state };
      }, { every: 100 });
      const r = await api('POST', path, body, { raw });
      const sent = raw ?? JSON.stringify(body);
      note(`POST ${path} ${sent.length > 90 ? `${sent.slice(0, 90)}...` : sent} -> ${r.status} ${r.text.slice(0, 160)}`);
      check(r.status >= 400 && r.status < 500, `answered ${r.status}, not 4xx: ${r.text.slice(0, 200)}`);
      check(r.json && typeof r.json.error === 'string' && r.json.error.length > 0,
        `the body is not {"error": "..."}: ${r.text.slice(0, 200)}`);
      check(r.status === expected, `answered ${r.status}, the spec says ${expected}: ${r.json.error}`);
      if (mention) check(mention.test(r.json.error), `the error does not name ${mention}: ${r.json.error}`);
      await sleep(300);
      const after = await status();
      check(maxAbsDiff(after.setpoints, before.setpoints) < 1e-6,
        `the setpoints changed: ${fmt(before.setpoints)} -> ${fmt(after.setpoints)}`);
      check(maxAbsDiff(after.measured, before.measured) < 0.002, `the arm moved: ${fmt(before.measured)} -> ${fmt(after.measured)}`);
      check(after.state === 'Idle' && after.torque === before.torque,
        `state ${before.state}/torque ${before.torque} became ${after.state}/torque ${after.torque}`);
    });
  }

  // g. -----------------------------------------------------------------------------------------
  const rest = async () => until(5000, 'the arm was not at rest', async () => {
    const s = await status();
    return s.state === 'Idle' ? s : { done: false, state: s.state };
  }, { every: 100 });
  // Joints well away from where the arm stands, within the limits: toward the middle of each range.
  const awayFrom = (q) => q.map((x, j) => {
    const { lower, upper } = arm.joints[j];
    const towards = x < (lower + upper) / 2 ? 1 : -1;
    return Number((x + towards * Math.min(0.5, (upper - lower) / 3)).toFixed(4));
  });
  const wrongToken = token.slice(0, -1) + (token.endsWith('0') ? '1' : '0');
  const own = `${base.protocol}//${base.host}`;
  const refusals = [
    ['GET /api/status without the token', 'GET', '/api/status', {}, 403],
    ['GET /api/status with a wrong token (the last character)', 'GET', '/api/status', { authorization: `Bearer ${wrongToken}` }, 403],
    ['GET /api/status with the token in the query, wrong', 'GET', `/api/status?token=${wrongToken}`, {}, 403],
    ['GET /api/status with the token and Origin: http://evil.example', 'GET', '/api/status',
      { authorization: `Bearer ${token}`, origin: 'http://evil.example' }, 403],
    ['GET /api/status with the token and Host: evil.example:PORT', 'GET', '/api/status',
      { authorization: `Bearer ${token}`, host: `evil.example:${base.port}` }, 403],
    ['POST /api/joints with the token and Content-Type: text/plain', 'POST', '/api/joints',
      { authorization: `Bearer ${token}`, 'content-type': 'text/plain' }, 415],
    ['a websocket to /api/ws without the token', 'WS', '/api/ws', {}, 403],
    ['a websocket to /api/ws with a wrong token', 'WS', `/api/ws?token=${wrongToken}`, {}, 403],
    // The same with what is right, so that the refusals above are the token's, Origin's or Host's.
    ['(control) GET /api/status with the token and Origin: http://127.0.0.1:PORT', 'GET', '/api/status',
      { authorization: `Bearer ${token}`, origin: own, host: base.host }, 200],
    ['(control) a websocket to /api/ws?token=TOKEN', 'WS', `/api/ws?token=${token}`, { origin: own }, 101],
  ];
  for (const [what, method, path, headers, expected] of refusals) {
    const verb = expected >= 400 ? `is refused ${expected}` : `is accepted ${expected}`;
    await step(`access: ${what} ${verb}`, async () => {
      const before = await rest();
      const body = method === 'POST' ? JSON.stringify({ q: awayFrom(before.setpoints) }) : undefined;
      const r = await rawRequest(method === 'WS' ? 'GET' : method, path, { headers, body, upgrade: method === 'WS' });
      note(`${method} ${path.replace(token, 'TOKEN').replace(wrongToken, 'WRONG')} -> ${r.status} ${r.text.slice(0, 160)}`);
      check(r.status === expected, `answered ${r.status}, expected ${expected}: ${r.text.slice(0, 200)}`);
      if (expected >= 400) {
        check(r.json && typeof r.json.error === 'string' && r.json.error.length > 0,
          `the body is not {"error": "..."}: ${r.text.slice(0, 200)}`);
      }
      if (method === 'POST') {
        await sleep(300);
        const after = await status();
        check(maxAbsDiff(after.setpoints, before.setpoints) < 1e-6,
          `the setpoints changed: ${fmt(before.setpoints)} -> ${fmt(after.setpoints)}`);
      }
    });
  }

  await step('a hostile page on another origin cannot drive the arm (no-cors POSTs, websocket)', async () => {
    const before = await rest();
    check(before.torque === true, `the torque was off before the attack: ${JSON.stringify(before.torque)}`);
    const q = awayFrom(before.setpoints);
    const csv = `${['t', ...arm.joints.map((_, j) => `q${j + 1}`)].join(',')}\n0.5,${q.join(',')}\n1.0,${q.join(',')}\n`;
    const attack = { view: base.origin, q, csv };
    // What a malicious site does: "simple" requests, which a browser sends without asking (no
    // preflight), and a websocket, which is not bound by the same-origin policy.
    const html = `<!doctype html><title>hostile</title><script>
const { view, q, csv } = ${JSON.stringify(attack)};
window.__attack = (async () => {
  const results = {};
  const send = async (name, path, body) => {
    try {
      const r = await fetch(view + path, { method: 'POST', mode: 'no-cors',
        headers: { 'Content-Type': 'text/plain' }, body: JSON.stringify(body) });
      results[name] = 'sent, answered (' + r.type + ')';
    } catch (e) {
      results[name] = 'failed: ' + e.message;
    }
  };
  await send('joints', '/api/joints', { q });
  await send('torque', '/api/torque', { on: false });
  await send('play', '/api/play', { name: 'evil.csv', csv });
  results.websocket = await new Promise((resolve) => {
    const ws = new WebSocket(view.replace(/^http/, 'ws') + '/api/ws');
    ws.onopen = () => { ws.close(); resolve('opened'); };
    ws.onerror = () => resolve('failed to open');
    setTimeout(() => resolve('neither opened nor failed within 3 s'), 3000);
  });
  return results;
})();
</script>`;
    const hostile = createServer((req, res) => {
      res.writeHead(req.url === '/' ? 200 : 404, { 'content-type': 'text/html; charset=utf-8' });
      res.end(req.url === '/' ? html : 'not found');
    });
    await new Promise((resolve, reject) => {
      hostile.once('error', reject);
      hostile.listen(0, '127.0.0.1', resolve);
    });
    const evilPage = await page.context().newPage();
    try {
      const evil = `http://127.0.0.1:${hostile.address().port}/`;
      check(new URL(evil).origin !== base.origin, 'the hostile page has the same origin as the view');
      const response = await evilPage.goto(evil, { waitUntil: 'load', timeout: 15_000 });
      check(response && response.status() === 200, `the hostile page answered ${response?.status()}`);
      const results = await evilPage.evaluate(() => window.__attack);
      note(`hostile page ${evil} tried POST /api/joints ${JSON.stringify({ q })}, /api/torque {"on":false}, ` +
        `/api/play, a websocket: ${JSON.stringify(results)}`);
      check(results.websocket === 'failed to open', `the hostile page's websocket: ${results.websocket}`);
      const t0 = Date.now();
      while (Date.now() - t0 < 500) {
        const s = await status();
        check(maxAbsDiff(s.setpoints, before.setpoints) < 1e-3,
          `the arm moved: setpoints ${fmt(before.setpoints)} -> ${fmt(s.setpoints)}`);
        check(s.torque === true, 'the torque went off');
        check(s.state === 'Idle', `the state became ${s.state} (play ${JSON.stringify(s.play)})`);
        await sleep(100);
      }
      note(`over 0.5 s after the attack: setpoints ${fmt((await status()).setpoints)}, torque on, Idle`);
    } finally {
      await evilPage.close().catch(() => {});
      hostile.closeAllConnections?.();
      await new Promise((resolve) => hostile.close(resolve));
    }
  });

  // f. -----------------------------------------------------------------------------------------
  await step('cost: websocket messages per second and the server\'s CPU, page open (cost.json)', async () => {
    check(await page.locator('#connection[data-connected="true"]').count() === 1, 'the page is not connected');
    const ticksPerSecond = (() => {
      try {
        return Number(execFileSync('getconf', ['CLK_TCK'], { encoding: 'utf8' }).trim()) || 100;
      } catch {
        return 100;
      }
    })();
    const cpuTicks = () => {
      const stat = readFileSync(`/proc/${server.pid}/stat`, 'utf8');
      const fields = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
      return Number(fields[11]) + Number(fields[12]); // utime + stime (fields 14 and 15)
    };
    const measureCpu = async (body) => {
      const ticks0 = cpuTicks();
      const t0 = process.hrtime.bigint();
      const value = await body();
      const wall = Number(process.hrtime.bigint() - t0) / 1e9;
      return { value, wall, percent: (100 * (cpuTicks() - ticks0)) / ticksPerSecond / wall };
    };
    const wsUrl = new URL(`/api/ws?token=${encodeURIComponent(token)}`, base).href.replace(/^http/, 'ws');
    await page.evaluate((u) => new Promise((resolve, reject) => {
      const ws = new WebSocket(u);
      window.__cost = { ws, counting: false, count: 0, bytes: 0, bad: 0, first: null, last: null, rate: null };
      ws.onmessage = (event) => {
        const c = window.__cost;
        if (!c.counting) return;
        c.count += 1;
        c.bytes += event.data.length;
        try {
          const m = JSON.parse(event.data);
          if (c.last !== null && !(m.seq > c.last)) c.bad += 1;
          if (c.first === null) c.first = m.seq;
          c.last = m.seq;
          c.rate = m.rate_hz;
        } catch {
          c.bad += 1;
        }
      };
      ws.onopen = () => resolve();
      ws.onerror = () => reject(new Error(`websocket ${u} failed`));
      setTimeout(() => reject(new Error(`websocket ${u} did not open within 5 s`)), 5000);
    }), wsUrl);
    const open = await measureCpu(() => page.evaluate(() => new Promise((resolve) => {
      const c = window.__cost;
      const t0 = performance.now();
      c.counting = true;
      setTimeout(() => {
        c.counting = false;
        c.ws.close();
        resolve({ count: c.count, bytes: c.bytes, bad: c.bad, first: c.first, last: c.last, rate: c.rate,
          seconds: (performance.now() - t0) / 1000 });
      }, 5000);
    })));
    const w = open.value;
    const perSecond = w.count / w.seconds;
    const seqSpan = w.first === null ? 0 : w.last - w.first + 1;
    // The same without any client: the page away, its websocket closed.
    await page.goto('about:blank');
    await sleep(500);
    const idle = await measureCpu(() => sleep(3000));
    const cost = {
      seconds: Number(w.seconds.toFixed(2)),
      websocket_messages: w.count,
      websocket_msgs_per_s: Number(perSecond.toFixed(1)),
      websocket_bytes_per_s: Math.round(w.bytes / w.seconds),
      seq_advanced_per_s: Number((seqSpan / w.seconds).toFixed(1)),
      server_rate_hz: w.rate,
      server_cpu_percent_of_one_core: Number(open.percent.toFixed(1)),
      server_cpu_percent_no_client: Number(idle.percent.toFixed(1)),
      websocket_clients_while_measured: 2,
      clk_tck: ticksPerSecond,
      cores: Number(execFileSync('nproc', { encoding: 'utf8' }).trim()),
    };
    writeFileSync(join(OUT, 'cost.json'), `${JSON.stringify(cost, null, 2)}\n`);
    console.log(`cost: websocket ${cost.websocket_msgs_per_s} msg/s, server CPU ${cost.server_cpu_percent_of_one_core} % of one core`);
    note(`(${cost.websocket_bytes_per_s} B/s; seq advanced ${cost.seq_advanced_per_s}/s; server rate_hz ${w.rate}; ` +
      `2 websocket clients: the page and this count; server CPU with no client ${cost.server_cpu_percent_no_client} %)`);
    check(w.bad === 0, `${w.bad} websocket messages were not telemetry with an increasing seq`);
    check(perSecond >= 10, `only ${perSecond.toFixed(1)} websocket messages per second`);
  });

  // ---------------------------------------------------------------------------------------------
  await step('the page threw no uncaught error', async () => {
    if (consoleErrors.length) note(`console errors (not failures): ${consoleErrors.slice(0, 8).join(' | ')}`);
    check(pageErrors.length === 0, `${pageErrors.length}: ${pageErrors.slice(0, 5).join(' | ')}`);
  });

  await Promise.race([browser.close().catch(() => {}), sleep(10_000)]);
  browser = null;
  await step('SIGINT ends the server within 5 s', async () => {
    check(!serverExit, `the server had already exited: ${JSON.stringify(serverExit)}`);
    const exit = await stopServer('SIGINT', 5000);
    check(exit, 'still running 5 s after SIGINT (killed)');
    note(`armctl view exited with ${JSON.stringify(exit)}`);
  });
}

let code = 0;
try {
  await main();
} catch (error) {
  console.log(`not ok - setup: ${String(error?.stack ?? error)}`);
  code = 1;
}
await cleanup();
clearTimeout(watchdog);
const failed = results.filter((r) => !r.ok).length;
if (failed || code) {
  const tail = serverStderr.trim().split('\n').slice(-30);
  if (tail.length && tail[0]) {
    note('armctl view stderr (last lines):');
    for (const line of tail) note(`  ${line}`);
  }
}
console.log(`e2e: ${results.length - failed} passed, ${failed} failed`);
process.exit(failed || code ? 1 : 0);
