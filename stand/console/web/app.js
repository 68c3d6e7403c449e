// The fpss-stand web console: hash-routed pages over the JSON API (docs/console.md); charts by uPlot.
'use strict';
const $ = (id) => document.getElementById(id);
const state = { token: '', page: '', liveRun: '', es: null, timers: [] };
window.fpssLatencies = [];  // point done (events.jsonl utc) -> residual chart drawn, ms

// ---- token and requests ----
function loadToken() {
  const m = location.hash.match(/token=([0-9a-f]{32,128})/);
  if (m) {
    localStorage.setItem('fpssToken', m[1]);
    history.replaceState(null, '', location.pathname + '#stand');
  }
  state.token = localStorage.getItem('fpssToken') || '';
  if (state.token) document.cookie = 'fpss_console=' + state.token + '; SameSite=Strict; path=/';
  $('token-state').textContent = state.token ? 'control: yes' : 'read only (open the URL with #token=... printed by serve)';
}
async function api(method, path, body) {
  const headers = {};
  if (state.token) headers['Authorization'] = 'Bearer ' + state.token;
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  const r = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  const j = await r.json().catch(() => ({}));
  if (!r.ok) throw new Error(j.error || (r.status + ' ' + r.statusText));
  return j;
}
const esc = (s) => String(s === undefined || s === null ? '' : s).replace(/[&<>"']/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' }[c]));
const fmt = (v, d = 2) => (typeof v === 'number' && isFinite(v) ? v.toFixed(d) : '-');
// A <select> refilled with `names`, keeping the operator's choice when it is still offered.
function fillSelect(sel, names) {
  const old = sel.value;
  sel.innerHTML = names.map((n) => '<option>' + esc(n) + '</option>').join('');
  if (old) sel.value = old;
}

// ---- router ----
function every(ms, f) { f(); state.timers.push(setInterval(f, ms)); }
function show() {
  state.timers.forEach(clearInterval);
  state.timers = [];
  const page = (location.hash.replace('#', '').split('/')[0]) || 'stand';
  state.page = page;
  document.querySelectorAll('.page').forEach((p) => p.classList.toggle('active', p.id === 'page-' + page));
  document.querySelectorAll('header nav a').forEach((a) => a.classList.toggle('active', a.id === 'nav-' + page));
  if (page === 'stand') every(1000, standPage);
  if (page === 'start') { loadProcedures(); every(1000, queuePage); }
  if (page === 'live') every(1000, livePoll);
  if (page === 'runs') runsPage();
  if (page === 'units') unitsPage();
  if (page === 'fleet') every(2000, fleetPage);
  if (page === 'investigations') every(5000, investigationsPage);
}

// ---- stand ----
async function standPage() {
  const s = await api('GET', '/api/stand').catch(() => null);
  if (!s) return;
  const g = s.gimbal || {}, n = s.sensor || {};
  const rows = [['bench', s.mode + (s.stand_file ? ' ' + s.stand_file : '') + (s.emulator_args ? ' ' + s.emulator_args.join(' ') : '')],
    ['connection', s.connected ? 'connected' : 'idle (no run holds the bench)'], ['state', s.state],
    ['run', s.run_id || '-'], ['gimbal pitch / yaw (arcsec)', g.point ? fmt(g.pitch_arcsec, 1) + ' / ' + fmt(g.yaw_arcsec, 1) + ' (point ' + g.point + ')' : '-'],
    ['sensor stream', n.rows !== undefined ? n.rows + ' frames, ' + n.invalid_frames + ' invalid, ' + n.attempts + ' attempt(s)' : '-'],
    ['temperature (C)', fmt(s.temperature_c, 1)], ['last fault', s.last_fault || '-'], ['last warning', s.last_warning || '-']];
  $('stand-table').innerHTML = rows.map(([k, v]) => '<tr><th>' + esc(k) + '</th><td>' + esc(v) + '</td></tr>').join('');
}

// ---- start and queue ----
async function loadProcedures() {
  fillSelect($('start-procedure'), await api('GET', '/api/procedures').catch(() => []));
}
async function queuePage() {
  const jobs = await api('GET', '/api/jobs').catch(() => []);
  const queued = jobs.filter((j) => j.state === 'queued');
  $('queue-table').innerHTML = '<tr><th>#</th><th>kind</th><th>procedure</th><th>unit</th><th>operator</th><th>state</th><th>run</th><th></th></tr>' +
    jobs.map((j) => '<tr><td>' + j.id + '</td><td>' + esc(j.kind) + '</td><td>' + esc(j.procedure) + '</td><td>' + esc(j.unit) + '</td><td>' + esc(j.operator) +
      '</td><td class="job-state">' + esc(j.state) + (j.exit_code >= 0 ? ' (exit ' + j.exit_code + ')' : '') + '</td><td>' + (j.run_id ? '<a href="#runs/' + esc(j.run_id) + '">' + esc(j.run_id) + '</a>' : '') +
      (j.investigation ? ' <a href="#investigations">investigation</a>' : '') + '</td><td>' +
      (j.state === 'queued' ? '<button data-up="' + j.id + '">up</button><button data-down="' + j.id + '">down</button><button data-rm="' + j.id + '">remove</button>' : '') + '</td></tr>').join('');
  $('queue-table').querySelectorAll('button').forEach((b) => b.onclick = async () => {
    const id = b.dataset.up || b.dataset.down || b.dataset.rm;
    const at = queued.findIndex((j) => String(j.id) === id);
    if (b.dataset.rm) await api('DELETE', '/api/jobs/' + id).catch(alertError);
    else await api('POST', '/api/jobs/' + id + '/move', { to: Math.max(0, at + (b.dataset.up ? -1 : 1)) }).catch(alertError);
    queuePage();
  });
}
function alertError(e) { $('start-message').textContent = 'error: ' + e.message; }
$('start-form').onsubmit = async (ev) => {
  ev.preventDefault();
  const kind = $('start-kind').value;
  const body = { kind, procedure: kind === 'run' ? $('start-procedure').value : '', unit: $('start-unit').value, operator: $('start-operator').value };
  if (kind === 'investigate') body.model = $('start-model').value;
  // The last submission's answer would otherwise stand until this one's comes, naming the wrong job.
  $('start-message').textContent = 'queuing...';
  try {
    const j = await api('POST', '/api/jobs', body);
    $('start-message').textContent = 'queued job ' + j.id;
  } catch (e) { alertError(e); }
  queuePage();
};

// ---- live run ----
const live = { total: 0, done: 0, t0: 0, res: [], targets: [], chart: null, map: null, pendingDone: {} };
function resetLive(runId) {
  if (state.es) state.es.close();
  Object.assign(live, { total: 0, done: 0, t0: 0, res: [], targets: [], pendingDone: {} });
  $('event-log').textContent = '';
  Object.assign(frame, { lines: [], chart: false, done: [] });
  $('live-run-id').textContent = runId;
  $('live-state').textContent = '';
  $('live-progress').value = 0;
  for (const id of ['live-progress-text', 'live-point', 'live-eta', 'live-fit']) $(id).textContent = '-';
  $('live-report').hidden = true;
  $('prompt-box').hidden = true;
  makeCharts();
  state.es = new EventSource('/api/runs/' + encodeURIComponent(runId) + '/stream');
  state.es.onmessage = (m) => onEvent(JSON.parse(m.data));
}
function makeCharts() {
  $('chart-residual').innerHTML = '';
  $('chart-map').innerHTML = '';
  const pts = (c) => ({ paths: () => null, points: { show: true, size: 6, stroke: c, fill: c } });
  live.chart = new uPlot({ width: 520, height: 300, scales: { x: { time: false } }, legend: { show: true },
    series: [{ label: 'angle (arcsec)' }, Object.assign({ label: 'pitch residual (arcsec)' }, pts('#1f77b4')), Object.assign({ label: 'yaw residual (arcsec)' }, pts('#d62728'))],
    axes: [{ label: 'reference angle (arcsec)' }, { label: 'residual (arcsec)' }] }, [[], [], []], $('chart-residual'));
  live.map = new uPlot({ width: 420, height: 300, scales: { x: { time: false } }, legend: { show: false },
    series: [{}, { paths: () => null, points: { show: false } }],
    axes: [{ label: 'pitch (arcsec)' }, { label: 'yaw (arcsec)' }],
    hooks: { draw: [drawMap] } }, [[], []], $('chart-map'));
}
// The residual map: a marker per point at its position, colour by |residual| (uPlot's scales, canvas hook).
function drawMap(u) {
  const ctx = u.ctx;
  const worst = Math.max(1e-9, ...live.res.map((r) => Math.hypot(r.rp, r.ry)));
  for (const r of live.res) {
    const x = u.valToPos(r.p, 'x', true), y = u.valToPos(r.y, 'y', true);
    const f = Math.hypot(r.rp, r.ry) / worst;
    ctx.fillStyle = 'rgb(' + Math.round(255 * f) + ',60,' + Math.round(255 * (1 - f)) + ')';
    ctx.beginPath();
    ctx.arc(x, y, 6 * devicePixelRatio, 0, 2 * Math.PI);
    ctx.fill();
  }
}
function redrawCharts() {
  const xs = [...new Set(live.res.flatMap((r) => [r.p, r.y]))].sort((a, b) => a - b);
  const at = new Map(xs.map((x, i) => [x, i]));
  const yp = xs.map(() => null), yy = xs.map(() => null);
  for (const r of live.res) { yp[at.get(r.p)] = r.rp; yy[at.get(r.y)] = r.ry; }
  live.chart.setData([xs, yp, yy]);
  const tx = live.targets.map((t) => t[1]).sort((a, b) => a - b);
  const ty = live.targets.map((t) => t[2]);
  if (tx.length) live.map.setData([tx, ty.sort((a, b) => a - b)]);
  else live.map.redraw();
}
// Log lines and chart points are drawn once per animation frame, however many events arrive.
const frame = { lines: [], chart: false, done: [], queued: false };
function schedule() {
  if (frame.queued) return;
  frame.queued = true;
  requestAnimationFrame(() => {
    frame.queued = false;
    if (frame.lines.length) {
      const el = $('event-log');
      let t = el.textContent + frame.lines.join('');
      if (t.length > 60000) t = t.slice(-40000);
      el.textContent = t;
      el.scrollTop = el.scrollHeight;
      frame.lines = [];
    }
    if (frame.chart) {
      redrawCharts();
      frame.chart = false;
      const now = Date.now();
      for (const t of frame.done) window.fpssLatencies.push(now - t);
      frame.done = [];
      $('chart-residual').dataset.points = live.res.length;
    }
  });
}
function logLine(e) {
  const { type, utc, ...rest } = e;
  frame.lines.push(utc + ' ' + type + ' ' + JSON.stringify(rest).slice(0, 200) + '\n');
  schedule();
}
function showProgress(done) {
  live.done = done;
  const p = live.total ? live.done / live.total : 0;
  $('live-progress').value = p;
  $('live-progress-text').textContent = live.done + ' / ' + live.total + ' points';
  const el = (Date.now() - live.t0) / 1000;
  $('live-eta').textContent = p > 0 && p < 1 ? Math.round(el / p - el) + ' s' : '-';
}
function onEvent(e) {
  if (e.type !== 'samples') logLine(e);
  if (e.type === 'run_started') {
    live.total = e.points_total; live.done = e.first_point - 1; live.t0 = Date.now(); live.targets = e.points || [];
    $('live-state').textContent = 'running';
  } else if (e.type === 'point_started') {
    $('live-point').textContent = e.point + ' (' + e.phase + ', pitch ' + fmt(e.target_pitch_arcsec, 0) + ', yaw ' + fmt(e.target_yaw_arcsec, 0) + ' arcsec)';
  } else if (e.type === 'point_done') {
    live.pendingDone[e.point] = Date.parse(e.utc);
    showProgress(e.point);
  } else if (e.type === 'step_stopped') {
    // An adaptive stop: the group's remaining points are not measured (they count as done).
    showProgress(e.first_skipped_point + e.points_skipped - 1);
    $('live-fit').textContent += '; ' + e.reason;
  } else if (e.type === 'point_residual') {
    live.res.push({ p: e.ref_pitch_arcsec, y: e.ref_yaw_arcsec, rp: e.residual_pitch_arcsec, ry: e.residual_yaw_arcsec });
    frame.chart = true;
    // Point done -> chart, for points whose residual was written with them (those before the first
    // valid live fit are written when it comes, and are not a measure of the console).
    const t = live.pendingDone[e.point];
    if (t && Date.parse(e.utc) - t < 100) frame.done.push(t);
    schedule();
  } else if (e.type === 'fit_updated') {
    $('live-fit').textContent = 'rms pitch ' + fmt(e.rms_pitch_arcsec) + ', yaw ' + fmt(e.rms_yaw_arcsec) + ' arcsec; 1-sigma ' +
      fmt(e.sigma_max_pitch_arcsec) + ' / ' + fmt(e.sigma_max_yaw_arcsec) + ' (' + e.pairs + ' pairs)';
  } else if (e.type === 'paused') {
    $('live-state').textContent = 'paused';
  } else if (e.type === 'resumed') {
    $('live-state').textContent = 'running';
  } else if (e.type === 'prompt') {
    showPrompt(e);
  } else if (e.type === 'prompt_answered') {
    $('prompt-box').hidden = true;
  } else if (e.type === 'prompt_rejected') {
    live.rejected = e.message;
  } else if (e.type === 'run_stopped') {
    $('live-state').textContent = e.cause === 'aborted' ? 'aborted' : e.outcome;
    $('live-state').dataset.cause = e.cause;
    $('live-state').dataset.safe = e.safe_state;
    if (state.es) state.es.close();
    showReportLink();
  }
}
async function showReportLink() {
  const run = $('live-run-id').textContent;
  for (let i = 0; i < 60; i++) {
    const r = await api('GET', '/api/runs/' + encodeURIComponent(run)).catch(() => null);
    if (r && !r.live && r.files && r.files['report.html']) {
      $('live-report').href = r.files['report.html'];
      $('live-report').hidden = false;
      return;
    }
    if (r && !r.live && i > 20) return;
    await new Promise((ok) => setTimeout(ok, 500));
  }
}
function showPrompt(e) {
  $('prompt-box').hidden = false;
  $('prompt-box').dataset.id = e.id;
  $('prompt-box').dataset.kind = e.kind;
  $('prompt-text').textContent = e.text;
  $('prompt-note').textContent = live.rejected || '';
  live.rejected = '';
  $('prompt-input').value = '';
  const confirm = e.kind === 'confirm';
  $('prompt-input').hidden = confirm; $('prompt-send').hidden = confirm;
  $('prompt-yes').hidden = !confirm; $('prompt-no').hidden = !confirm;
  if (!confirm) $('prompt-input').focus();
}
async function answer(value) {
  const run = $('live-run-id').textContent;
  await api('POST', '/api/runs/' + encodeURIComponent(run) + '/answer', { id: $('prompt-box').dataset.id, value })
    .catch((e) => { $('prompt-note').textContent = 'error: ' + e.message; });
}
$('prompt-send').onclick = () => answer($('prompt-input').value);
$('prompt-input').onkeydown = (ev) => { if (ev.key === 'Enter') answer($('prompt-input').value); };
$('prompt-yes').onclick = () => answer('yes');
$('prompt-no').onclick = () => answer('no');
async function control(action) {
  const run = $('live-run-id').textContent;
  for (let attempt = 1; attempt <= 3; attempt++) {
    try {
      await api('POST', '/api/runs/' + encodeURIComponent(run) + '/control', { action });
      return;
    } catch (e) {
      logLine({ type: 'control_error', utc: new Date().toISOString(), message: action + ': ' + e.message });
      await new Promise((ok) => setTimeout(ok, 300));
    }
  }
}
$('btn-pause').onclick = () => control('pause');
$('btn-resume').onclick = () => control('resume');
$('btn-abort').onclick = () => control('abort');
async function livePoll() {
  const want = location.hash.split('/')[1];
  if (want) { if (want !== state.liveRun) { state.liveRun = want; resetLive(want); } return; }
  const s = await api('GET', '/api/status').catch(() => null);
  if (!s) return;
  let run = s.live_runs[0];
  if (!run) { const last = s.jobs.filter((j) => j.run_id).pop(); run = last && last.run_id; }
  if (run && run !== state.liveRun) { state.liveRun = run; resetLive(run); }
  if (!run) $('live-state').textContent = 'no run yet: queue one on the Start page';
}

// ---- runs ----
async function runsPage() {
  const q = new URLSearchParams({ unit: $('f-unit').value, outcome: $('f-outcome').value, from: $('f-from').value, to: $('f-to').value });
  const runs = await api('GET', '/api/runs?' + q).catch(() => []);
  $('runs-table').innerHTML = '<tr><th>run</th><th>unit</th><th>procedure</th><th>started</th><th>outcome</th><th>points</th><th>verdict</th><th>operator</th></tr>' +
    runs.map((r) => '<tr><td><a href="#runs/' + esc(r.run_id) + '">' + esc(r.run_id) + '</a></td><td>' + esc(r.unit) + '</td><td>' + esc(r.procedure) + '</td><td>' + esc(r.started_utc) +
      '</td><td>' + esc(r.outcome) + '</td><td>' + (r.points ? r.points.completed + '/' + r.points.total : '') + '</td><td>' + esc(r.verdict) + '</td><td>' + esc(r.operator) + '</td></tr>').join('');
  const id = location.hash.split('/')[1];
  $('run-detail').innerHTML = '';
  if (!id) return;
  const r = await api('GET', '/api/runs/' + encodeURIComponent(id)).catch(() => null);
  if (!r) return;
  const names = { 'report.html': 'report', 'GAP.html': 'GAP report', 'certificate.txt': 'certificate', 'acceptance.json': 'acceptance.json', 'samples.csv': 'samples.csv download', 'run.json': 'run.json' };
  $('run-detail').innerHTML = '<h2>' + esc(r.run_id) + '</h2><p>' + esc(r.outcome) + (r.stop_cause ? ' (' + esc(r.stop_cause) + ')' : '') + (r.reason ? ': ' + esc(r.reason) : '') +
    (r.live ? ' <a href="#live/' + esc(r.run_id) + '">watch live</a>' : '') + '</p><ul>' +
    Object.entries(names).filter(([f]) => r.files[f]).map(([f, n]) => '<li><a class="run-file" href="' + esc(r.files[f]) + '"' + (f === 'samples.csv' ? ' download' : ' target="_blank"') + '>' + n + '</a></li>').join('') + '</ul>' +
    (r.units ? '<table id="run-units"><tr><th>unit</th><th>outcome</th><th>verdict</th><th>relative to the first (arcsec)</th><th>files</th></tr>' +
      r.units.map((u) => '<tr class="run-unit"><td>' + esc(u.serial) + '</td><td>' + esc(u.outcome) + (u.loss_cause ? ' (' + esc(u.loss_cause) + ')' : '') +
        '</td><td>' + esc(u.verdict || '') + '</td><td>' + (u.relative ? 'boresight ' + u.relative.boresight_pitch_arcsec.toFixed(3) + ', ' + u.relative.boresight_yaw_arcsec.toFixed(3) +
        '; roll ' + u.relative.roll_arcsec.toFixed(2) : '') + '</td><td>' +
        Object.entries(names).filter(([f]) => u.files[f]).map(([f, n]) => '<a class="run-file" href="' + esc(u.files[f]) + '"' + (f === 'samples.csv' ? ' download' : ' target="_blank"') + '>' + n + '</a>').join(' ') +
        '</td></tr>').join('') + '</table>' : '');
}
$('runs-filter').onsubmit = (ev) => { ev.preventDefault(); runsPage(); };

// ---- investigations ----
async function investigationsPage() {
  const list = await api('GET', '/api/investigations').catch(() => []);
  $('investigations-table').innerHTML = '<tr><th>investigation</th><th>stopped</th><th>verdict</th><th>causes</th><th>still ambiguous</th>' +
    '<th>neither named nor bounded</th><th>runs</th></tr>' +
    list.map((i) => '<tr class="investigation"><td>' + (i.files['INVESTIGATION.html']
      ? '<a class="investigation-report" target="_blank" href="' + esc(i.files['INVESTIGATION.html']) + '">' + esc(i.name) + '</a>' : esc(i.name)) +
      '</td><td title="' + esc(i.stop_sentence || '') + '">' + esc(i.stop_reason || '') + '</td><td title="' + esc(i.no_diagnosis || '') + '">' + esc(i.verdict || (i.no_diagnosis ? 'no diagnosis' : '')) + '</td><td>' +
      esc(i.causes.map((c) => c.name).join(', ')) + '</td><td>' + esc(i.ambiguous.map((m) => m.join(' / ')).join('; ')) + '</td><td>' +
      esc((i.unbounded || []).join(', ')) + '</td><td>' + i.runs.map((r) => '<a href="#runs/' + esc(r) + '">' + esc(r) + '</a>').join('<br>') + '</td></tr>').join('');
}

// ---- unit history ----
async function unitsPage() {
  const units = await api('GET', '/api/units').catch(() => []);
  const sel = $('unit-select');
  fillSelect(sel, units);
  sel.onchange = unitHistory;
  unitHistory();
}
async function unitHistory() {
  const u = $('unit-select').value;
  if (!u) return;
  const h = await api('GET', '/api/units/' + encodeURIComponent(u) + '/history').catch(() => null);
  if (!h) return;
  const acc = {};
  h.acceptances.forEach((a) => { if (a.run_id) acc[a.run_id] = a; });
  $('unit-table').innerHTML = '<tr><th>id</th><th>date</th><th>source</th><th>label</th><th>pitch mean |r|</th><th>yaw mean |r|</th><th>acceptance</th></tr>' +
    h.calibrations.map((c) => '<tr><td>' + c.id + '</td><td>' + esc(c.date_utc) + '</td><td>' + esc(c.source) + '</td><td>' + esc(c.label) + '</td><td>' +
      fmt(c.pitch && c.pitch.mean_abs_arcsec, 3) + '</td><td>' + fmt(c.yaw && c.yaw.mean_abs_arcsec, 3) + '</td><td>' +
      (c.run_id && acc[c.run_id] ? (acc[c.run_id].passed ? 'pass' : 'fail') + ' ' + esc(acc[c.run_id].operator) : '') + '</td></tr>').join('');
  const opts = h.calibrations.map((c) => '<option value="' + c.id + '">' + c.id + ' ' + esc(c.date_utc) + ' ' + esc(c.label) + '</option>').join('');
  $('cmp-a').innerHTML = opts; $('cmp-b').innerHTML = opts;
  if (h.calibrations.length > 1) $('cmp-b').selectedIndex = h.calibrations.length - 1;
}
$('cmp-go').onclick = async () => {
  const c = await api('GET', '/api/compare?a=' + $('cmp-a').value + '&b=' + $('cmp-b').value).catch((e) => { $('cmp-summary').textContent = e.message; });
  if (!c) return;
  $('cmp-summary').textContent = 'alpha: max ' + fmt(c.alpha.max_abs_arcsec) + ' arcsec, rms ' + fmt(c.alpha.rms_arcsec) + '; beta: max ' + fmt(c.beta.max_abs_arcsec) + ' arcsec, rms ' + fmt(c.beta.rms_arcsec);
  $('chart-compare').innerHTML = '';
  for (const ax of ['alpha', 'beta']) {
    new uPlot({ width: 480, height: 260, title: ax + ': B - A', scales: { x: { time: false } },
      series: [{ label: 'angle under A (arcsec)' }, { label: 'B - A (arcsec)', stroke: ax === 'alpha' ? '#1f77b4' : '#d62728' }],
      axes: [{ label: 'angle under A (arcsec)' }, { label: 'B - A (arcsec)' }] }, [c[ax].angle_a_arcsec, c[ax].diff_arcsec], $('chart-compare'));
  }
};

// ---- fleet ----
async function fleetPage() {
  const f = await api('GET', '/api/fleet').catch(() => null);
  if (!f) return;
  $('fleet-stands').innerHTML = '<tr><th>stand</th><th>last run</th><th>unit</th><th>procedure</th><th>started</th><th>state</th></tr>' +
    f.stands.map((r) => '<tr><td>' + esc(r.stand) + '</td><td>' + esc(r.run_id) + '</td><td>' + esc(r.unit) + '</td><td>' + esc(r.procedure) +
      '</td><td>' + esc(r.started_utc) + '</td><td class="' + (r.live ? 'live' : '') + '">' + (r.live ? 'live' : esc(r.outcome)) + '</td></tr>').join('');
  $('fleet-units').innerHTML = '<tr><th>unit</th><th>latest verdict</th><th>date</th><th>stand</th></tr>' +
    f.units.map((u) => '<tr><td>' + esc(u.unit) + '</td><td>' + (u.verdict ? esc(u.verdict) : 'not accepted yet') + '</td><td>' + esc(u.date_utc) +
      '</td><td>' + esc(u.stand) + '</td></tr>').join('');
  const m = f.msa;
  $('fleet-msa-note').textContent = m ? m.file + ': ' + m.units.length + ' units x ' + m.stands.length + ' stands (' + m.stands.join(', ') + ') x ' + m.repeats + ' repeats'
    : 'none yet: fpss-stand msa --out RUNS_DIR/msa/NAME.json (docs/fleet.md)';
  $('fleet-msa').innerHTML = m ? '<tr><th>quantity</th><th>%GRR of tolerance</th><th>%GRR of TV</th><th>ndc</th><th>reading</th></tr>' +
    m.quantities.map((q) => '<tr><td>' + esc(q.name) + '</td><td>' + fmt(q.grr_percent_tolerance, 1) + '</td><td>' + fmt(q.grr_percent_tv, 1) +
      '</td><td>' + esc(q.ndc) + '</td><td>' + esc(q.verdict) + '</td></tr>').join('') : '';
}

window.addEventListener('hashchange', show);
loadToken();
show();
