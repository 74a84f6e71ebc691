// Talking to the `armctl view` server (its API: docs/view.md; every error is
// {"error": "..."}).

const listeners = [];

/**
 * The token armctl printed in the page's URL (?token=...): the server answers the API only to
 * requests that carry it, so that no other site's page can drive the arm from this browser. It
 * is kept for this tab (a reload finds it) and taken out of the address bar, so that it is not
 * in a screenshot, the history or a copied link.
 */
const token = (() => {
  const params = new URLSearchParams(location.search);
  const given = params.get('token');
  if (given) {
    sessionStorage.setItem('armctl-view-token', given);
    params.delete('token');
    const rest = params.toString();
    history.replaceState(null, '', location.pathname + (rest ? `?${rest}` : '') + location.hash);
  }
  return given || sessionStorage.getItem('armctl-view-token') || '';
})();

/** The header every API request carries (for fetch and three.js loaders). */
export function authHeaders() { return { authorization: `Bearer ${token}` }; }

/** Called with (message) for every failed request, so the page can show it in #error. */
export function onRequestError(fn) { listeners.push(fn); }

function report(message) { for (const fn of listeners) fn(message); }

/**
 * POST a JSON body. Resolves to {ok, status, body}; never throws, because every caller
 * wants to show the failure in words where it happened rather than lose it in the console.
 * `quiet` keeps a failure out of #error (the caller shows it itself).
 */
export async function post(path, body, { quiet = false } = {}) {
  let res;
  try {
    res = await fetch(path, {
      method: 'POST',
      headers: { 'content-type': 'application/json', ...authHeaders() },
      body: JSON.stringify(body),
    });
  } catch (e) {
    const error = `cannot reach the server (${path}): ${e.message}`;
    if (!quiet) report(error);
    return { ok: false, status: 0, body: { error } };
  }
  let data = null;
  const text = await res.text();
  try { data = text ? JSON.parse(text) : {}; } catch { data = { error: text.trim() || res.statusText }; }
  if (!res.ok) {
    if (!data || typeof data.error !== 'string') data = { ...(data || {}), error: `${path}: HTTP ${res.status} ${res.statusText}` };
    if (!quiet) report(data.error);
  }
  return { ok: res.ok, status: res.status, body: data };
}

export async function getJSON(path) {
  const res = await fetch(path, { headers: authHeaders() });
  const text = await res.text();
  let data;
  try { data = JSON.parse(text); } catch { throw new Error(`${path}: not JSON (HTTP ${res.status})`); }
  if (!res.ok) throw new Error(data.error || `${path}: HTTP ${res.status}`);
  return data;
}

/**
 * Keeps one websocket to /api/ws open, reconnecting every second after a close.
 * onMessage gets each parsed telemetry object; onClose() is called when the socket closes.
 */
export function connectTelemetry({ onMessage, onClose }) {
  let ws = null;
  const open = () => {
    // A browser cannot set a header on a websocket: the token goes in the query.
    const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/api/ws?token=${encodeURIComponent(token)}`;
    ws = new WebSocket(url);
    ws.onmessage = (ev) => {
      let t;
      try { t = JSON.parse(ev.data); } catch { return; }
      onMessage(t);
    };
    ws.onclose = () => {
      onClose();
      setTimeout(open, 1000);
    };
    // An error is always followed by close, which does the retry.
    ws.onerror = () => {};
  };
  open();
  return { close: () => { if (ws) { ws.onclose = null; ws.close(); } } };
}
