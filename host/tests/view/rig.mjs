// End-to-end browser test of `armctl view --rig bimanual-so101` (contract: the server's JSON API,
// the page's ids and window.armView).
//
// Starts `$ARMCTL view --rig bimanual-so101 --listen 127.0.0.1:0`, opens its page in headless
// Chromium (Debian's, driven by playwright-core, flags as e2e.mjs) and checks, each as a named step
// printing `ok - name` or `not ok - name: reason`:
//   a. the page loads, its websocket connects, and it lists both arms with their telemetry;
//   b. the 3D view draws both arms, each at its base in the world frame (0.3 m apart on y), and
//      the pixels where each arm's first link should be are the arm's, not the background;
//   c. picking the second arm (right) makes the controls drive it: slider #joint-1 moves the right
//      arm and not the left; a world-frame target typed in and sent with Go brings the right arm's
//      tool there (within 1 mm);
//   d. STOP stops both arms while both move;
// then that the page threw no uncaught error and that SIGINT ends the server.
// Exit code 1 when any step failed. The server and the browser are always ended; the whole run
// is bounded by OVERALL_MS.
//
// Environment: ARMCTL (the binary, required), VIEW_E2E_OUT (folder for screenshots, default ./out),
// CHROMIUM (default /usr/bin/chromium).
// Run by host/tests/view_browser.rs; by hand: ARMCTL=target/debug/armctl node host/tests/view/rig.mjs

import { spawn } from 'node:child_process';
import { mkdirSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { chromium } from 'playwright-core';
import { CHROMIUM_ARGS, check, decodePng, differingPixels, distance, fmt, maxAbsDiff, note, sleep, until } from './harness.mjs';

const OVERALL_MS = 150_000;
const ARMCTL = process.env.ARMCTL;
const OUT = process.env.VIEW_E2E_OUT || 'out';
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const RIG = 'bimanual-so101';
const BASES = { left: [0, 0.15, 0], right: [0, -0.15, 0] };

if (!ARMCTL) {
  console.log('not ok - setup: set ARMCTL to the armctl binary');
  process.exit(1);
}
mkdirSync(OUT, { recursive: true });

const results = [];
let shots = 0;
let page = null;

async function screenshot(name) {
  shots += 1;
  const path = join(OUT, `rig-${String(shots).padStart(2, '0')}-${name}.png`);
  await page.screenshot({ path, fullPage: true, timeout: 15_000 });
  note(`screenshot ${path}`);
  return path;
}

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

// ---------------------------------------------------------------------------------------------
// The server.

let server = null;
let serverExit = null;
let serverStderr = '';
let base = null;
let token = null;

function startServer() {
  server = spawn(ARMCTL, ['view', '--rig', RIG, '--listen', '127.0.0.1:0'], { stdio: ['ignore', 'pipe', 'pipe'] });
  server.stderr.setEncoding('utf8');
  server.stderr.on('data', (d) => { serverStderr += d; });
  const exited = new Promise((resolve) => {
    server.on('exit', (code, signal) => { serverExit = { code, signal }; resolve(serverExit); });
    server.on('error', (error) => { serverExit = { code: null, signal: null, error: error.message }; resolve(serverExit); });
  });
  return new Promise((resolve, reject) => {
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

/// One request to the API from node, with the token: {status, text, json}.
async function api(method, path, body) {
  const init = { method, signal: AbortSignal.timeout(5000), headers: { authorization: `Bearer ${token}` } };
  if (body !== undefined) {
    init.headers['content-type'] = 'application/json';
    init.body = JSON.stringify(body);
  }
  const response = await fetch(new URL(path, base), init);
  const text = await response.text();
  let json = null;
  try { json = JSON.parse(text); } catch { /* left null: the callers say what they expected */ }
  return { status: response.status, text, json };
}

/// One arm's telemetry.
async function status(arm) {
  const r = await api('GET', `/api/arm/${arm}/status`);
  check(r.status === 200 && r.json, `GET /api/arm/${arm}/status answered ${r.status}: ${r.text.slice(0, 200)}`);
  return r.json;
}

/// Holding, or limp as it starts (torque off): not moving.
const rest = (arm) => until(8000, `arm ${arm} did not come to rest`, async () => {
  const s = await status(arm);
  return s.state === 'Idle' || s.state === 'TorqueOff' ? s : { done: false, state: s.state };
}, { every: 100 });

// ---------------------------------------------------------------------------------------------
// The run.

let browser = null;
const pageErrors = [];

async function cleanup() {
  if (browser) await Promise.race([browser.close().catch(() => {}), sleep(10_000)]);
  browser = null;
  await stopServer('SIGINT', 3000);
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
  await step(`armctl view --rig ${RIG} --listen 127.0.0.1:0 starts and prints its URL first`, async () => {
    url = await started;
    note(`URL ${url}`);
    base = new URL(url);
    token = base.searchParams.get('token');
    check(base.hostname === '127.0.0.1' && token && token.length >= 32, `not the page's URL with a token: ${url}`);
  });
  if (!base) return;
  const rig = (await api('GET', '/api/rig')).json;
  check(rig && Array.isArray(rig.arms), 'GET /api/rig gave no arms');
  note(`rig ${rig.name}: ${rig.arms.map((a) => `${a.name} at ${fmt(a.base.p, 2)}`).join(', ')}`);

  browser = await chromium.launch({ executablePath: CHROMIUM, args: CHROMIUM_ARGS, headless: true, timeout: 60_000 });
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 }, deviceScaleFactor: 1 });
  page = await context.newPage();
  page.setDefaultTimeout(15_000);
  page.on('pageerror', (error) => pageErrors.push(String(error?.message ?? error).split('\n')[0]));

  // a. -----------------------------------------------------------------------------------------
  await step('the page loads, connects, and lists both arms with their telemetry', async () => {
    const response = await page.goto(url, { waitUntil: 'load', timeout: 30_000 });
    check(response && response.status() === 200, `GET / answered ${response?.status()}`);
    await page.waitForSelector('#connection[data-connected="true"]', { timeout: 15_000 });
    check(await page.locator('#rig-section').isVisible(), '#rig-section is hidden');
    const names = await page.evaluate(() => window.armView.arms());
    check(JSON.stringify(names) === JSON.stringify(['left', 'right']), `armView.arms() is ${JSON.stringify(names)}`);
    for (const arm of names) {
      const shown = await until(5000, `#arm-${arm}-state does not show a state`, async () => {
        const text = await page.locator(`#arm-${arm}-state`).textContent();
        return /Idle|TorqueOff|Moving/.test(text) ? text : { done: false, text };
      }, { every: 100 });
      const tool = await page.locator(`#arm-${arm}-tool`).textContent();
      const y = Number(tool.split(',')[1]);
      note(`#arm-${arm}-state ${JSON.stringify(shown)}, #arm-${arm}-tool ${JSON.stringify(tool)}`);
      check(Math.sign(y) === Math.sign(BASES[arm][1]), `arm ${arm}'s tool ${tool} is not on its side of the world (y)`);
    }
    check(await page.evaluate(() => window.armView.selected()) === 'left', 'the first arm is not the one driven at first');
    check((await page.locator('#target-frame').textContent()).includes('world'), 'the target is not said in the world frame');
  });

  // b. -----------------------------------------------------------------------------------------
  await step('the 3D view draws both arms, each at its base in the world frame', async () => {
    const drawn = await until(10_000, 'armView.drawnArms() does not show two chains', async () => {
      const d = await page.evaluate(() => window.armView.drawnArms());
      return d.length === 2 && d.every((a) => a.shown) ? d : { done: false, d };
    }, { every: 100 });
    for (const [i, arm] of ['left', 'right'].entries()) {
      check(distance(drawn[i].base, BASES[arm]) < 1e-9, `arm ${arm}'s chain starts at ${fmt(drawn[i].base)}, not its base`);
    }
    // Both arms stand at the same joints: every point of the left chain is the right's 0.3 m along y.
    const [l, r] = [await status('left'), await status('right')];
    if (maxAbsDiff(l.measured, r.measured) < 1e-3) {
      for (let k = 1; k < drawn[0].points.length; k++) {
        const shift = drawn[0].points[k].map((x, j) => x - drawn[1].points[k][j]);
        check(distance(shift, [0, 0.3, 0]) < 1e-3, `point ${k}: left - right = ${fmt(shift)}, not [0, 0.3, 0]`);
      }
    }
    await page.evaluate(() => new Promise((resolve) => {
      let frames = 0;
      const tick = () => (++frames >= 10 ? resolve() : requestAnimationFrame(tick));
      requestAnimationFrame(tick);
    }));
    await sleep(1000);
    const shot = await page.screenshot({ fullPage: true, timeout: 15_000 });
    shots += 1;
    const path = join(OUT, `rig-${String(shots).padStart(2, '0')}-both-arms.png`);
    writeFileSync(path, shot);
    note(`screenshot ${path}`);
    const image = decodePng(shot);
    const canvas = await page.locator('canvas#view3d').boundingBox();
    const background = (() => {
      const p = (Math.round(canvas.y + 3) * image.width + Math.round(canvas.x + 3)) * image.channels;
      return [image.data[p], image.data[p + 1], image.data[p + 2]];
    })();
    // Around the middle of each arm's first link: mostly the arm's pixels, not the background
    // (a grid line is one pixel wide and would not fill the window).
    for (const [i, arm] of ['left', 'right'].entries()) {
      const { x, y } = drawn[i].link;
      let differ = 0, all = 0;
      for (let dy = -3; dy <= 3; dy++) {
        for (let dx = -3; dx <= 3; dx++) {
          const p = (Math.round(y + dy) * image.width + Math.round(x + dx)) * image.channels;
          const d = Math.max(...[0, 1, 2].map((c) => Math.abs(image.data[p + c] - background[c])));
          all += 1;
          if (d > 24) differ += 1;
        }
      }
      note(`arm ${arm}: first link at (${fmt(x, 1)}, ${fmt(y, 1)}) px, ${differ} of ${all} pixels there differ from the background`);
      check(x > canvas.x && x < canvas.x + canvas.width && y > canvas.y && y < canvas.y + canvas.height,
        `arm ${arm}'s first link is off the canvas`);
      check(differ >= 0.6 * all, `arm ${arm} is not drawn where its first link is (${differ} of ${all} pixels differ)`);
    }
    const whole = differingPixels(decodePng(await page.locator('canvas#view3d').screenshot()));
    check(whole.differing / whole.total > 0.01 && whole.colours >= 4, 'the canvas looks blank');
  });

  // c. -----------------------------------------------------------------------------------------
  await step('picking the right arm: slider #joint-1 moves the right arm, not the left', async () => {
    await page.locator('#arm-pick-right').check();
    await until(3000, 'armView.selected() did not become right', async () =>
      (await page.evaluate(() => window.armView.selected())) === 'right', { every: 50 });
    check((await page.locator('#arm-name').textContent()).includes('driving right'), '#arm-name does not say right');
    const [left0, right0] = [await rest('left'), await rest('right')];
    // The target moved to the picked arm's tool, in the world frame.
    const target = await page.evaluate(() => window.armView.target());
    check(target && distance(target, right0.tool) < 2e-3, `the target ${fmt(target)} is not at the right arm's tool ${fmt(right0.tool)}`);
    const slider = page.locator('#joint-1');
    const goal = Math.abs(right0.measured[1] - 0.5) < 0.2 ? 0.1 : 0.5;
    const posted = page.waitForResponse((r) => r.url().endsWith('/api/arm/right/joints') && r.request().method() === 'POST',
      { timeout: 5000 });
    posted.catch(() => {});
    await slider.evaluate((el) => {
      window.__changes = 0;
      el.addEventListener('change', () => window.__changes++);
    });
    await slider.fill(String(goal));
    // As e2e.mjs: a change by hand only where fill dispatched none (a second one would send the
    // sliders as they are then).
    if (await page.evaluate(() => window.__changes) === 0) {
      await slider.evaluate((el) => el.dispatchEvent(new Event('change', { bubbles: true })));
    }
    const response = await posted.catch(() => null);
    check(response, 'the page sent no POST /api/arm/right/joints within 5 s of the slider\'s change');
    note(`page sent POST /api/arm/right/joints ${response.request().postData()} -> ${response.status()}`);
    check(response.status() === 200, `POST /api/arm/right/joints answered ${response.status()}`);
    const moved = await until(10_000, `right measured[1] did not reach ${goal}`, async () => {
      const s = await status('right');
      return Math.abs(s.measured[1] - goal) <= 0.01 ? s : {
        done: false, state: s.state, measured: s.measured, setpoints: s.setpoints, last_error: s.last_error,
        lost_servos: s.lost_servos, errors: s.errors,
      };
    }, { every: 100 });
    note(`right measured[1] = ${fmt(moved.measured[1])}`);
    const left1 = await status('left');
    check(maxAbsDiff(left1.setpoints, left0.setpoints) < 1e-6, `the left arm moved: ${fmt(left0.setpoints)} -> ${fmt(left1.setpoints)}`);
  });

  await step('a world-frame target typed in and sent with Go brings the right arm\'s tool there (within 1 mm)', async () => {
    const right0 = await rest('right');
    const left0 = await status('left');
    // "At tool" puts the target on the driven arm's tool, in the world frame.
    await page.locator('#target-to-tool').click();
    const target0 = await until(3000, 'the target is not at the right arm\'s tool', async () => {
      const t = await page.evaluate(() => window.armView.target());
      return t && distance(t, right0.tool) < 2e-3 ? t : { done: false, t, tool: right0.tool };
    }, { every: 100 });
    const goal = [target0[0] + 0.02, target0[1] - 0.02, target0[2] + 0.015].map((x) => Number(x.toFixed(3)));
    for (const [i, axis] of ['x', 'y', 'z'].entries()) {
      await page.locator(`#target-${axis}`).fill(String(goal[i]));
      await page.locator(`#target-${axis}`).evaluate((el) => el.dispatchEvent(new Event('change', { bubbles: true })));
    }
    const posted = page.waitForResponse((r) => r.url().endsWith('/api/arm/right/target') && r.request().method() === 'POST'
      && JSON.parse(r.request().postData() || '{}').go === true, { timeout: 5000 });
    posted.catch(() => {});
    await sleep(200);
    await page.locator('#go').click();
    const response = await posted.catch(() => null);
    check(response, 'the page sent no POST /api/arm/right/target with go within 5 s of Go');
    note(`page sent POST /api/arm/right/target ${response.request().postData()} -> ${response.status()} ${(await response.text()).slice(0, 120)}`);
    check(response.status() === 200, `POST /api/arm/right/target answered ${response.status()}`);
    const reached = await until(10_000, 'the right arm\'s tool did not reach the target within 1 mm', async () => {
      const s = await status('right');
      const d = distance(s.tool, goal);
      return d <= 0.001 && s.state === 'Idle' ? { s, d } : { done: false, tool: s.tool, mm: d * 1000 };
    }, { every: 100 });
    note(`right tool ${fmt(reached.s.tool)} is ${(reached.d * 1000).toFixed(2)} mm from ${fmt(goal)} (world frame)`);
    const left1 = await status('left');
    check(maxAbsDiff(left1.setpoints, left0.setpoints) < 1e-6, 'the left arm moved');
    await screenshot('right-at-target');
  });

  // d. -----------------------------------------------------------------------------------------
  await step('STOP stops both arms while both move (Idle within 3 s, short of their goals)', async () => {
    await rest('left');
    await rest('right');
    const goals = { left: [1.2, 0, 0, 0, 0], right: [-1.2, 0, 0, 0, 0] };
    for (const arm of ['left', 'right']) {
      const r = await api('POST', `/api/arm/${arm}/joints`, { q: goals[arm], speed: 0.4 });
      check(r.status === 200, `POST /api/arm/${arm}/joints answered ${r.status} ${r.text}`);
    }
    for (const arm of ['left', 'right']) {
      await until(3000, `arm ${arm} is not moving`, async () => (await status(arm)).state === 'Moving', { every: 50 });
    }
    const stopped = page.waitForResponse((r) => r.url().endsWith('/api/stop') && r.request().method() === 'POST', { timeout: 5000 });
    stopped.catch(() => {});
    await page.locator('#stop').click();
    const response = await stopped.catch(() => null);
    check(response && response.status() === 200, `POST /api/stop answered ${response?.status()}`);
    const body = await response.json();
    note(`POST /api/stop -> ${JSON.stringify(body)}`);
    check(body.arms && body.arms.left?.ok && body.arms.right?.ok, 'the stop did not reach both arms');
    for (const arm of ['left', 'right']) {
      const s = await until(3000, `arm ${arm} did not stop`, async () => {
        const st = await status(arm);
        return st.state === 'Idle' ? st : { done: false, state: st.state };
      }, { every: 50 });
      check(maxAbsDiff(s.setpoints, goals[arm]) > 0.2, `arm ${arm} reached its goal: it was not stopped`);
    }
  });

  await step('the page threw no uncaught error', async () => {
    check(pageErrors.length === 0, `${pageErrors.length}: ${pageErrors.slice(0, 5).join(' | ')}`);
  });

  await Promise.race([browser.close().catch(() => {}), sleep(10_000)]);
  browser = null;
  await step('SIGINT ends the server within 5 s, both arms stopped', async () => {
    const exit = await stopServer('SIGINT', 5000);
    check(exit, 'still running 5 s after SIGINT (killed)');
    check(/arm left: stopped/.test(serverStderr) && /arm right: stopped/.test(serverStderr),
      'stderr does not say both arms stopped');
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
console.log(`rig e2e: ${results.length - failed} passed, ${failed} failed`);
process.exit(failed || code ? 1 : 0);
