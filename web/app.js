// mfcd operator view: polls the daemon's JSON views once a second and shows them.
// Plain JS, no libraries, nothing from outside the cell. Every string from the daemon goes into
// the page as text (textContent), never as markup. Read-only: it only sends GETs.
'use strict';

const POLL_MS = 1000;          // one round of requests per second
const REQUEST_TIMEOUT_MS = 2500;
const PLOT_CYCLES = 120;       // cycles kept for the time plot
const IMAGES = ['ambient', 'edges', 'overlay'];

const state = {
  history: [],                 // [{cycle, ms, overrun}] of the cycles seen, oldest first
  budgetMs: null,
  shownCycle: null,            // the cycle the images were loaded for
  seen: {},                    // endpoint -> last JSON text rendered (re-render on change only)
  parts: {},                   // obj_id -> part name (status.parts, status.recipes)
};

const $ = (id) => document.getElementById(id);

function text(id, value) {
  const el = $(id);
  if (el) el.textContent = value === undefined || value === null || value === '' ? '–' : String(value);
}

function yesNo(v) {
  return v === undefined || v === null ? '–' : (v ? 'yes' : 'no');
}

function num(v, digits) {
  return typeof v === 'number' && isFinite(v) ? v.toFixed(digits) : '–';
}

function el(tag, content, cls) {
  const e = document.createElement(tag);
  if (content !== undefined && content !== null) e.textContent = String(content);
  if (cls) e.className = cls;
  return e;
}

function clear(node) {
  while (node.firstChild) node.removeChild(node.firstChild);
}

async function getJson(path) {
  const abort = new AbortController();
  const timer = setTimeout(() => abort.abort(), REQUEST_TIMEOUT_MS);
  try {
    const res = await fetch(path, {cache: 'no-store', signal: abort.signal});
    if (!res.ok) throw new Error(path + ': HTTP ' + res.status);
    return await res.json();
  } finally {
    clearTimeout(timer);
  }
}

// ---- status -------------------------------------------------------------------------------

function renderStatus(s) {
  if (!s || typeof s !== 'object') return;
  const stateEl = $('status-state');
  text('status-state', s.state);
  stateEl.dataset.state = s.state || '';
  text('status-ready', yesNo(s.ready));
  text('status-vision-ok', yesNo(s.vision_ok));
  text('status-error-code', s.error_code);
  const recipe = (s.recipes || []).find((r) => r.id === s.recipe);
  text('status-recipe', s.recipe === undefined ? null : s.recipe + (recipe && recipe.part ? ' (' + recipe.part + ')' : ''));
  text('status-camera', s.camera);
  text('status-modbus-clients', s.modbus ? s.modbus.clients : null);
  text('status-version', s.version);
  text('status-commit', s.commit);
  if (typeof s.cycle_budget_ms === 'number') state.budgetMs = s.cycle_budget_ms;

  for (const p of s.parts || []) state.parts[p.obj_id] = p.name;
  for (const r of s.recipes || []) if (r.obj_id && r.part && !(r.obj_id in state.parts)) state.parts[r.obj_id] = r.part;

  const tbody = $('recipes-table').tBodies[0];
  clear(tbody);
  for (const r of s.recipes || []) {
    const tr = el('tr', null, r.id === s.recipe ? 'selected' : '');
    tr.append(el('td', r.id), el('td', r.part), el('td', r.obj_id));
    tbody.append(tr);
  }
  if (!(s.recipes || []).length) {
    const tr = el('tr');
    const td = el('td', 'none', 'muted');
    td.colSpan = 3;
    tr.append(td);
    tbody.append(tr);
  }
  $('calibration-state').textContent = s.calibration === undefined ? '–' : JSON.stringify(s.calibration, null, 2);
}

// ---- last cycle ---------------------------------------------------------------------------

function renderLast(j) {
  // /api/last is the result itself; a control-socket style {"result": ...} is accepted too.
  const r = j && typeof j === 'object' && 'result' in j && !('cycle' in j) ? j.result : j;
  const section = $('last-cycle');
  if (!r || typeof r !== 'object') {
    section.dataset.cycle = '';
    text('last-cycle-id', 'no cycle yet');
    return;
  }
  section.dataset.cycle = r.cycle;
  const total = r.times_ms ? r.times_ms.total : r.total_ms;
  text('last-cycle-id', r.cycle);
  text('last-job-id', r.job_id);
  text('last-total-ms', typeof total === 'number' ? total.toFixed(1) + ' ms' + (r.overrun ? ' (overrun)' : '') : null);
  const err = r.error && r.error !== 'none' ? r.error + (r.message ? ': ' + r.message : '') : 'none';
  text('last-error', err);
  $('last-error').className = err === 'none' ? '' : 'bad';
  if (typeof r.budget_ms === 'number') state.budgetMs = r.budget_ms;

  renderPick(r);
  renderCandidates(r);
  if (r.cycle !== state.shownCycle) {
    state.shownCycle = r.cycle;
    loadImages(r.cycle);
  }
  if (typeof total === 'number') {
    const last = state.history[state.history.length - 1];
    if (!last || last.cycle !== r.cycle) {
      state.history.push({cycle: r.cycle, ms: total, overrun: !!r.overrun});
      if (state.history.length > PLOT_CYCLES) state.history.shift();
      drawPlot();
    }
  }
}

function partName(objId) {
  return state.parts[objId] || '';
}

function renderPick(r) {
  const pick = $('pick');
  clear(pick);
  const p = r.pick;
  if (!p || typeof p !== 'object') {
    pick.className = 'pick none';
    pick.textContent = r.mode === 'count' ? 'count job: no pick' : 'no pick';
    return;
  }
  pick.className = 'pick';
  pick.append(el('span', 'pick', 'label'));
  for (const k of ['x', 'y', 'z']) pick.append(el('span', k + ' ' + num(p[k], 1) + ' mm', 'coord'));
  for (const k of ['rx', 'ry', 'rz']) pick.append(el('span', k + ' ' + num(p[k], 1) + '°', 'coord'));
  const name = partName(p.obj_id);
  pick.append(el('span', 'part ' + (name ? name + ' ' : '') + '(' + p.obj_id + ')', 'coord'));
  pick.append(el('span', 'score ' + num(p.score, 3), 'coord'));
}

function renderCandidates(r) {
  const tbody = $('candidates').tBodies[0];
  clear(tbody);
  const cands = Array.isArray(r.candidates) ? r.candidates : [];
  const ranked = Array.isArray(r.ranked) ? r.ranked : [];
  cands.forEach((c, i) => {
    const rank = ranked.indexOf(i);
    const tr = el('tr', null, i === r.chosen ? 'chosen' : (rank >= 0 ? 'ranked' : ''));
    const marker = i === r.chosen ? '★ chosen' : (rank >= 0 ? '#' + (rank + 1) : '');
    tr.append(el('td', i), el('td', partName(c.obj_id) || '–'), el('td', c.obj_id), el('td', num(c.score, 3)),
              el('td', c.ambiguous ? 'yes' : 'no', c.ambiguous ? 'warn' : ''), el('td', marker));
    tbody.append(tr);
  });
  if (!cands.length) {
    const tr = el('tr');
    const td = el('td', 'no candidates', 'muted');
    td.colSpan = 6;
    tr.append(td);
    tbody.append(tr);
  }
}

function loadImages(cycle) {
  for (const name of IMAGES) {
    const img = $(name);
    img.dataset.loaded = '0';
    img.onload = () => {
      img.dataset.loaded = '1';
      img.dataset.cycle = String(cycle);
      img.parentElement.classList.remove('missing');
    };
    img.onerror = () => {
      img.dataset.loaded = '0';
      img.parentElement.classList.add('missing');
    };
    img.src = '/api/image/' + name + '.png?cycle=' + encodeURIComponent(cycle);
  }
}

// ---- statistics and the time plot ----------------------------------------------------------

function renderStats(s) {
  if (!s || typeof s !== 'object') return;
  const t = s.percentiles_ms && s.percentiles_ms.total ? s.percentiles_ms.total : {};
  text('stats-percentiles', num(t.p50, 1) + ' / ' + num(t.p90, 1) + ' / ' + num(t.p99, 1) + ' ms');
  text('stats-cycles', s.cycles);
  text('stats-overruns', s.overruns);
  text('stats-errors', s.errors);
  if (typeof s.budget_ms === 'number') state.budgetMs = s.budget_ms;
  const tbody = $('pick-results').tBodies[0];
  clear(tbody);
  const pr = s.pick_results && typeof s.pick_results === 'object' ? s.pick_results : {};
  const order = ['ok', 'missed', 'unreachable', 'collision', 'dropped', 'reported', 'failed_share'];
  const keys = order.filter((k) => k in pr).concat(Object.keys(pr).filter((k) => !order.includes(k)));
  for (const k of keys) {
    const v = pr[k];
    const tr = el('tr');
    tr.append(el('td', k.replace(/_/g, ' ')), el('td', k === 'failed_share' ? num(100 * v, 1) + ' %' : v));
    tbody.append(tr);
  }
}

function drawPlot() {
  const canvas = $('cycle-plot');
  canvas.dataset.points = String(state.history.length);
  const ctx = canvas.getContext && canvas.getContext('2d');
  if (!ctx) return;
  // Drawn at the size it is shown, in device pixels, so the text stays sharp and legible.
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth || canvas.width, h = canvas.clientHeight || canvas.height;
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  const left = 44, right = 8, top = 8, bottom = 20;
  ctx.clearRect(0, 0, w, h);
  ctx.font = '11px sans-serif';
  ctx.fillStyle = '#555';
  const pts = state.history;
  if (!pts.length) return;
  let max = Math.max(...pts.map((p) => p.ms), state.budgetMs || 0) * 1.1;
  if (!(max > 0)) max = 1;
  const slots = Math.max(pts.length, 30);  // the first cycles spread out, then up to PLOT_CYCLES
  const x = (i) => left + (i * (w - left - right)) / (slots - 1);
  const y = (ms) => top + (h - top - bottom) * (1 - ms / max);

  // axes and scale
  ctx.strokeStyle = '#bbb';
  ctx.lineWidth = 1;
  ctx.beginPath();
  ctx.moveTo(left, top);
  ctx.lineTo(left, h - bottom);
  ctx.lineTo(w - right, h - bottom);
  ctx.stroke();
  ctx.textAlign = 'right';
  ctx.textBaseline = 'middle';
  for (const frac of [0, 0.5, 1]) {
    const ms = (max / 1.1) * frac;
    ctx.fillText(ms.toFixed(0), left - 4, y(ms));
  }
  ctx.textAlign = 'left';
  ctx.textBaseline = 'top';
  ctx.fillText('ms per cycle, last ' + pts.length + ' (cycles ' + pts[0].cycle + '–' + pts[pts.length - 1].cycle + ')',
               left + 4, h - bottom + 4);

  if (state.budgetMs) {  // the cycle budget
    ctx.strokeStyle = '#d08000';
    ctx.setLineDash([4, 4]);
    ctx.beginPath();
    ctx.moveTo(left, y(state.budgetMs));
    ctx.lineTo(w - right, y(state.budgetMs));
    ctx.stroke();
    ctx.setLineDash([]);
  }
  ctx.strokeStyle = '#2a6fdb';
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  pts.forEach((p, i) => (i ? ctx.lineTo(x(i), y(p.ms)) : ctx.moveTo(x(i), y(p.ms))));
  ctx.stroke();
  pts.forEach((p, i) => {
    ctx.fillStyle = p.overrun ? '#c62828' : '#2a6fdb';
    ctx.beginPath();
    ctx.arc(x(i), y(p.ms), p.overrun ? 3 : 2, 0, 2 * Math.PI);
    ctx.fill();
  });
}

// ---- snapshots ----------------------------------------------------------------------------

function renderSnapshots(j) {
  const given = Array.isArray(j) ? j : (j && Array.isArray(j.snapshots) ? j.snapshots : []);
  // Newest first: mfcd names a snapshot <UTC time>-cycle<N>.
  const nameOf = (s) => String(typeof s === 'string' ? s : (s && s.name) || '');
  const list = given.slice().sort((a, b) => (nameOf(a) < nameOf(b) ? 1 : nameOf(a) > nameOf(b) ? -1 : 0));
  $('snapshots-dir').textContent = j && j.directory ? j.directory : '';
  const ul = $('snapshot-list');
  clear(ul);
  for (const s of list) {
    const snap = typeof s === 'string' ? {name: s} : s;
    const li = el('li');
    li.append(el('span', snap.name, 'snapshot-name'));
    if (snap.cycle !== undefined) li.append(el('span', ' cycle ' + snap.cycle, 'muted'));
    const files = el('span', null, 'files');
    for (const f of snap.files || []) {
      const a = el('a', f);
      a.href = '/snapshots/' + encodeURIComponent(snap.name) + '/' + encodeURIComponent(f);
      a.setAttribute('download', f);
      files.append(a);
    }
    li.append(files);
    ul.append(li);
  }
  if (!list.length) ul.append(el('li', 'none', 'muted'));
}

// ---- the poll loop ------------------------------------------------------------------------

const views = [
  ['/api/status', renderStatus],
  ['/api/last', renderLast],
  ['/api/stats', renderStats],
  ['/api/snapshots', renderSnapshots],
];

async function poll() {
  let failed = 0;
  const results = await Promise.allSettled(views.map(([path]) => getJson(path)));
  results.forEach((r, i) => {
    const [path, render] = views[i];
    if (r.status !== 'fulfilled') {
      failed += 1;
      return;
    }
    const key = JSON.stringify(r.value);
    if (state.seen[path] === key) return;  // unchanged: the DOM stays as it is
    state.seen[path] = key;
    try {
      render(r.value);
    } catch (e) {
      console.error(path, e);
    }
  });
  const conn = $('conn');
  if (failed === 0) {
    conn.textContent = 'live · ' + new Date().toLocaleTimeString();
    conn.className = 'conn conn-ok';
  } else {
    conn.textContent = (failed === views.length ? 'no answer from mfcd' : failed + ' view(s) failed') +
                       ' · ' + new Date().toLocaleTimeString();
    conn.className = 'conn conn-bad';
  }
  setTimeout(poll, POLL_MS);
}

window.addEventListener('resize', drawPlot);
document.addEventListener('DOMContentLoaded', poll);
