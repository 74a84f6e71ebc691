// What the browser tests of `armctl view` share (e2e.mjs: one arm; rig.mjs: a rig's arms): the
// browser's flags, small helpers, waiting for a condition, and reading a screenshot's pixels.

import { inflateSync } from 'node:zlib';

/// Debian's Chromium, headless, without a GPU, talking to nothing but the page.
export const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  // WebGL without a GPU: the software rasteriser.
  '--enable-unsafe-swiftshader',
  '--use-angle=swiftshader',
];

export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
export const note = (text) => console.log(`# ${text}`);
export const fmt = (v, digits = 4) => (Array.isArray(v) ? `[${v.map((x) => fmt(x, digits)).join(', ')}]` : Number(v).toFixed(digits));
export const distance = (a, b) => Math.hypot(...a.map((x, i) => x - b[i]));
export const maxAbsDiff = (a, b) => Math.max(...a.map((x, i) => Math.abs(x - b[i])));

export function check(condition, message) {
  if (!condition) throw new Error(message);
}

/// Calls `probe` every `every` ms until it returns a truthy value (returned) or `ms` have passed
/// (throws `what`, with the last value `describe` makes of the probe's result).
export async function until(ms, what, probe, { every = 50, describe = (v) => JSON.stringify(v) } = {}) {
  const deadline = Date.now() + ms;
  let last;
  for (;;) {
    last = await probe();
    if (last && last.done !== false) return last;
    if (Date.now() > deadline) throw new Error(`${what} within ${ms / 1000} s; last: ${describe(last)}`);
    await sleep(every);
  }
}

// ---------------------------------------------------------------------------------------------
// A minimal PNG decoder (8-bit RGB or RGBA, not interlaced: what Chromium's screenshots are).

export function decodePng(buffer) {
  const signature = Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]);
  check(buffer.subarray(0, 8).equals(signature), 'not a PNG');
  let pos = 8;
  let header = null;
  const idat = [];
  while (pos + 8 <= buffer.length) {
    const length = buffer.readUInt32BE(pos);
    const type = buffer.toString('latin1', pos + 4, pos + 8);
    const data = buffer.subarray(pos + 8, pos + 8 + length);
    pos += 12 + length;
    if (type === 'IHDR') {
      header = {
        width: data.readUInt32BE(0),
        height: data.readUInt32BE(4),
        depth: data[8],
        colour: data[9],
        interlace: data[12],
      };
    } else if (type === 'IDAT') {
      idat.push(data);
    } else if (type === 'IEND') {
      break;
    }
  }
  check(header, 'PNG without IHDR');
  const { width, height, depth, colour, interlace } = header;
  check(depth === 8 && (colour === 2 || colour === 6) && interlace === 0,
    `unsupported PNG: depth ${depth}, colour type ${colour}, interlace ${interlace}`);
  const channels = colour === 6 ? 4 : 3;
  const stride = width * channels;
  const raw = inflateSync(Buffer.concat(idat));
  check(raw.length >= height * (stride + 1), 'PNG data too short');
  const out = Buffer.alloc(height * stride);
  for (let y = 0; y < height; y++) {
    const filter = raw[y * (stride + 1)];
    const src = y * (stride + 1) + 1;
    const row = y * stride;
    const up = row - stride;
    for (let x = 0; x < stride; x++) {
      const a = x >= channels ? out[row + x - channels] : 0;
      const b = y > 0 ? out[up + x] : 0;
      const c = x >= channels && y > 0 ? out[up + x - channels] : 0;
      let predictor;
      switch (filter) {
        case 0: predictor = 0; break;
        case 1: predictor = a; break;
        case 2: predictor = b; break;
        case 3: predictor = (a + b) >> 1; break;
        case 4: {
          const p = a + b - c;
          const pa = Math.abs(p - a);
          const pb = Math.abs(p - b);
          const pc = Math.abs(p - c);
          predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
          break;
        }
        default: throw new Error(`bad PNG filter ${filter} on row ${y}`);
      }
      out[row + x] = (raw[src + x] + predictor) & 0xff;
    }
  }
  return { width, height, channels, data: out };
}

/// How many pixels differ from the top-left corner's colour (by more than `tolerance` in a channel).
export function differingPixels(image, tolerance = 24) {
  const { width, height, channels, data } = image;
  const background = [data[0], data[1], data[2]];
  let differing = 0;
  const colours = new Set();
  for (let i = 0; i < width * height; i++) {
    const p = i * channels;
    const d = Math.max(
      Math.abs(data[p] - background[0]),
      Math.abs(data[p + 1] - background[1]),
      Math.abs(data[p + 2] - background[2]),
    );
    if (d > tolerance) differing += 1;
    if (colours.size < 4096) colours.add((data[p] >> 3) << 10 | (data[p + 1] >> 3) << 5 | (data[p + 2] >> 3));
  }
  return { differing, total: width * height, background, colours: colours.size };
}
