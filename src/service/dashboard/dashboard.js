// emplan dashboard script: reads the service's API, follows /api/events, draws the battery
// charts and the leg tables. Everything from the service is put in the page as text (never as
// markup). The token lives in the variable `token` only: never in storage, a cookie or the URL.
'use strict';
(() => {
  const $ = (id) => document.getElementById(id);
  let token = null;
  const state = {
    missions: [],
    selected: null,
    detail: null,
    battery: [],
    liveFlight: null,
    legs: new Map(),
    guard: null,
    guardNotes: [],
    flights: [],
    report: null,
    packs: [],
  };
  const CHART_WINDOW_MS = 5 * 60 * 1000;

  // ---- helpers -------------------------------------------------------------------------
  function el(tag, attrs, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === undefined || v === null) continue;
      if (k === 'class') e.className = v;
      else if (k === 'text') e.textContent = v;
      else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
      else if (k === 'width') e.style.width = v; // CSSOM: allowed by the page's style-src 'self'
      else e.setAttribute(k, v);
    }
    for (const c of children) {
      if (c === null || c === undefined) continue;
      e.append(c instanceof Node ? c : String(c));
    }
    return e;
  }
  const fmt = (v, digits) => (v === null || v === undefined || Number.isNaN(v) ? '-' : Number(v).toFixed(digits));
  const pct = (v) => (v === null || v === undefined ? '-' : (v >= 0 ? '+' : '') + Number(v).toFixed(1) + '%');
  const yesNo = (v) => (v === null || v === undefined ? '-' : v ? 'yes' : 'no');
  const enc = encodeURIComponent;

  async function api(path, options) {
    let response;
    try {
      response = await fetch(path, Object.assign({ cache: 'no-store' }, options || {}));
    } catch (e) {
      return { status: 0, ok: false, body: { ok: false, stage: 'network', error: String(e) } };
    }
    let body = null;
    try {
      body = await response.json();
    } catch (e) {
      body = null;
    }
    return { status: response.status, ok: response.ok, body };
  }

  // ---- the token: asked when needed, kept in memory only ---------------------------------
  let tokenWaiter = null;
  function askToken() {
    if (token) return Promise.resolve(token);
    const dialog = $('token-dialog');
    const input = $('token-input');
    input.value = '';
    dialog.hidden = false;
    input.focus();
    return new Promise((resolve) => {
      tokenWaiter = resolve;
    });
  }
  function closeTokenDialog(value) {
    const input = $('token-input');
    input.value = '';
    $('token-dialog').hidden = true;
    if (value) setToken(value);
    const waiter = tokenWaiter;
    tokenWaiter = null;
    if (waiter) waiter(value || null);
  }
  function setToken(value) {
    token = value;
    $('token-state').textContent = value ? 'Token: in memory' : 'Token: none';
    $('token-forget').hidden = !value;
  }
  $('token-ok').addEventListener('click', () => closeTokenDialog($('token-input').value.trim()));
  $('token-cancel').addEventListener('click', () => closeTokenDialog(null));
  $('token-input').addEventListener('keydown', (e) => {
    if (e.key === 'Enter') closeTokenDialog($('token-input').value.trim());
    if (e.key === 'Escape') closeTokenDialog(null);
  });
  $('token-forget').addEventListener('click', () => setToken(null));

  // A POST that changes the vehicle: asks for the token if none is held; a refused token is forgotten.
  async function authorizedPost(path, body) {
    const t = await askToken();
    if (!t) return null;
    const answer = await api(path, {
      method: 'POST',
      headers: { Authorization: 'Bearer ' + t, 'Content-Type': 'application/json' },
      body: JSON.stringify(body || {}),
    });
    if (answer.status === 401) setToken(null);
    return answer;
  }

  function showResult(box, kind, text) {
    box.className = 'result ' + kind;
    box.textContent = text;
  }
  function failureText(answer) {
    const b = answer.body || {};
    const parts = ['Failed at stage ' + (b.stage || 'request') + ' (HTTP ' + answer.status + '): ' + (b.error || 'no answer')];
    if (b.item !== null && b.item !== undefined) parts.push('item ' + b.item);
    if (b.result) parts.push('autopilot result ' + b.result);
    if (b.accepted) parts.push('the autopilot had accepted the transfer');
    return parts.join('; ');
  }

  // ---- views ---------------------------------------------------------------------------
  function show(view) {
    for (const name of ['missions', 'live', 'flights', 'packs']) {
      $('view-' + name).hidden = name !== view;
      $('tab-' + name).setAttribute('aria-pressed', String(name === view));
    }
    if (view === 'live') drawCharts();
    if (view === 'packs') loadPacks();
  }
  for (const tab of document.querySelectorAll('.tab')) {
    tab.addEventListener('click', () => show(tab.dataset.view));
  }

  // ---- missions ------------------------------------------------------------------------
  function missionStatus(m) {
    if (m.status === 'planned' && m.feasible === false) {
      return m.sorties ? 'infeasible: ' + m.sorties + ' sorties' : 'infeasible';
    }
    if (m.status === 'error' && m.error) {
      const where = m.error.line ? ' (line ' + m.error.line + ')' : m.error.item !== undefined ? ' (item ' + m.error.item + ')' : '';
      return 'error' + where;
    }
    return m.status;
  }
  function statusClass(m) {
    if (m.status === 'planned' && m.feasible === false) return 'status status-infeasible';
    return 'status status-' + m.status;
  }

  async function loadMissions() {
    const answer = await api('/api/missions');
    const body = $('missions-body');
    if (!answer.ok) {
      body.replaceChildren(el('tr', {}, el('td', { colspan: 5, class: 'bad', text: failureText(answer) })));
      return;
    }
    state.missions = answer.body.missions || [];
    $('missions-dir').textContent = 'Folder: ' + answer.body.dir;
    if (state.missions.length === 0) {
      body.replaceChildren(el('tr', {}, el('td', { colspan: 5, text: 'No mission files in the folder.' })));
    } else {
      body.replaceChildren(
        ...state.missions.map((m) =>
          el(
            'tr',
            {
              class: 'clickable' + (m.name === state.selected ? ' selected' : ''),
              tabindex: 0,
              'data-name': m.name,
              onclick: () => selectMission(m.name),
              onkeydown: (e) => {
                if (e.key === 'Enter') selectMission(m.name);
              },
            },
            el('td', { text: m.name }),
            el('td', { class: statusClass(m), text: missionStatus(m) }),
            el('td', { class: 'num', text: m.waypoints ?? '-' }),
            el('td', { class: 'num', text: fmt(m.energy_kj, 2) }),
            el('td', { class: 'num', text: m.saving_pct === undefined ? '-' : fmt(m.saving_pct, 1) + '%' }),
          ),
        ),
      );
    }
    if (!state.selected && state.missions.length > 0) selectMission(state.missions[0].name);
    else if (state.selected) selectMission(state.selected, true);
  }

  let lastPlotKey = null;
  async function selectMission(name, refresh) {
    state.selected = name;
    for (const row of $('missions-body').children) {
      row.classList.toggle('selected', row.dataset.name === name);
    }
    const answer = await api('/api/missions/' + enc(name));
    if (state.selected !== name) return;
    $('md-title').textContent = name;
    if (!answer.ok) {
      $('md-status').replaceChildren(el('p', { class: 'bad', text: failureText(answer) }));
      $('md-facts').replaceChildren();
      $('md-sorties').replaceChildren();
      $('md-upload').hidden = true;
      $('md-figure').hidden = true;
      return;
    }
    const m = answer.body;
    state.detail = m;
    $('md-status').replaceChildren(
      el('p', {}, 'Status: ', el('span', { class: statusClass(m), id: 'md-status-text', text: missionStatus(m) }), m.mission ? '  Mission ' + m.mission : ''),
    );
    const facts = [];
    const fact = (k, ...v) => facts.push(el('dt', { text: k }), el('dd', {}, ...v));
    if (m.status === 'error' && m.error) {
      const e = m.error;
      fact('Stage', e.stage);
      if (e.line) fact('Line', String(e.line));
      if (e.item !== undefined) fact('Item', String(e.item));
      fact('Error', el('span', { class: 'bad', text: e.message }));
    }
    const plan = m.plan;
    if (m.status === 'planned' && plan) {
      const order = (o) => (plan.orders || []).find((x) => x.objective === o);
      const energy = order('energy');
      const distance = (plan.orders || []).filter((x) => x.objective === 'distance').sort((a, b) => a.energy_kj - b.energy_kj)[0];
      if (energy) fact('Energy order', el('b', { text: fmt(energy.energy_kj, 2) + ' kJ' }), ' ', el('div', { class: 'seq', text: ['origin', ...energy.sequence, 'origin'].join(' > ') }));
      if (distance) fact('Distance order', fmt(distance.energy_kj, 2) + ' kJ (' + distance.direction + ')', el('div', { class: 'seq', text: ['origin', ...distance.sequence, 'origin'].join(' > ') }));
      if (m.saving_pct !== undefined && m.saving_pct !== null) fact('Saving', el('b', { text: fmt(m.saving_pct, 1) + '% of the distance order' }));
      const b = plan.battery;
      if (b) {
        fact(
          'Battery',
          el('span', { class: b.feasible ? 'good' : 'bad', text: b.feasible ? 'fits one battery' : 'INFEASIBLE on one battery' }),
          ': ' + fmt(b.total_kj, 2) + ' kJ of ' + fmt(b.budget_kj, 2) + ' kJ usable (' + fmt(b.reserve_pct, 0) + '% reserve)' + (b.feasible ? '' : ', over by ' + fmt(b.excess_kj, 2) + ' kJ'),
        );
      }
      fact('Profile', String(plan.profile));
    }
    $('md-facts').replaceChildren(...facts);
    renderSorties(m);
    $('md-upload').hidden = !(m.status === 'planned' || m.status === 'error');
    $('upload-btn').disabled = m.status !== 'planned';
    const sortieSelect = $('upload-sortie');
    const sorties = (plan && plan.sorties && plan.sorties.sorties) || [];
    if (!refresh || sortieSelect.options.length !== sorties.length + 1) {
      sortieSelect.replaceChildren(el('option', { value: '', text: 'whole mission' }), ...sorties.map((s, k) => el('option', { value: String(k + 1), text: 'sortie ' + (k + 1) })));
    }
    $('upload-sortie-label').hidden = sorties.length === 0;
    if (!refresh) $('upload-result').textContent = '';
    const plotKey = m.status === 'planned' ? name + '@' + m.digest : null;
    $('md-figure').hidden = plotKey === null;
    if (plotKey && plotKey !== lastPlotKey) {
      $('md-plot').src = '/api/missions/' + enc(name) + '/plot.svg?digest=' + enc(m.digest);
      $('md-plot-open').href = $('md-plot').src;
    }
    lastPlotKey = plotKey;
  }

  function renderSorties(m) {
    const box = $('md-sorties');
    const s = m.plan && m.plan.sorties;
    if (!s) {
      box.replaceChildren(...(m.sorties_error ? [el('p', { class: 'bad', text: 'Sorties: ' + m.sorties_error })] : []));
      return;
    }
    box.replaceChildren(
      el('h3', { text: 'Sorties: ' + s.sorties.length + ' batteries, ' + fmt(s.total_kj, 2) + ' kJ in all (' + (s.optimal ? 'optimal' : String(s.method)) + ')' }),
      el(
        'table',
        {},
        el('thead', {}, el('tr', {}, el('th', { text: 'Sortie' }), el('th', { text: 'Order' }), el('th', { class: 'num', text: 'kJ' }), el('th', { class: 'num', text: 'Battery' }))),
        el(
          'tbody',
          {},
          ...s.sorties.map((x, k) =>
            el('tr', {}, el('td', { class: 'num', text: String(k + 1) }), el('td', { class: 'seq', text: ['origin', ...x.sequence, 'origin'].join(' > ') }), el('td', { class: 'num', text: fmt(x.total_kj, 2) }), el('td', { class: 'num', text: fmt(x.budget_pct, 0) + '%' })),
          ),
        ),
      ),
    );
  }

  $('upload-btn').addEventListener('click', async () => {
    const name = state.selected;
    if (!name) return;
    const box = $('upload-result');
    const request = { order: $('upload-order').value, allow_infeasible: $('upload-infeasible').checked };
    const sortie = $('upload-sortie').value;
    if (sortie) request.sortie = Number(sortie);
    const pack = $('upload-pack').value.trim();
    if (pack) request.pack = pack;
    const button = $('upload-btn');
    button.disabled = true;
    showResult(box, 'busy', 'Uploading ' + name + '…');
    try {
      const answer = await authorizedPost('/api/missions/' + enc(name) + '/upload', request);
      if (answer === null) {
        showResult(box, 'fail', 'Not uploaded: no token entered.');
      } else if (answer.ok && answer.body && answer.body.ok !== false) {
        const d = answer.body;
        const lines = ['Uploaded and verified: ' + d.mission + ', ' + (d.order || request.order) + ' order' + (d.sortie ? ', sortie ' + d.sortie : '') + (pack ? ', pack ' + pack : '')];
        if (d.sequence) lines.push('Order: ' + ['origin', ...d.sequence, 'origin'].join(' > '));
        const r = d.report || {};
        lines.push((r.items ?? '-') + ' items sent, ' + (r.verified ? 'read back identical' : 'NOT verified') + (d.autopilot ? ' (' + d.autopilot.flavour + ' autopilot)' : ''));
        if (d.predicted_mission_kj !== undefined) lines.push('Predicted ' + fmt(d.predicted_mission_kj, 2) + ' kJ of ' + fmt(d.budget_kj, 2) + ' kJ');
        showResult(box, r.verified ? 'ok' : 'fail', lines.join('\n'));
        box.dataset.outcome = r.verified ? 'verified' : 'failed';
      } else {
        showResult(box, 'fail', failureText(answer));
        box.dataset.outcome = 'failed';
      }
    } finally {
      button.disabled = state.detail && state.detail.status !== 'planned';
    }
  });

  // ---- live flight ---------------------------------------------------------------------
  function setText(id, text) {
    $(id).textContent = text;
  }
  function applyLink(link) {
    if (!link) return;
    const text = link.state.replace(/_/g, ' ') + (link.builtin_mock ? ' (built-in mock)' : '');
    setText('lv-link', text);
    setText('hdr-link', link.state.replace(/_/g, ' '));
  }
  function applyTelemetry(t) {
    if (!t) return;
    setText('lv-link', t.link.replace(/_/g, ' '));
    setText('hdr-link', t.link.replace(/_/g, ' '));
    setText('lv-armed', yesNo(t.armed));
    setText('hdr-armed', yesNo(t.armed));
    setText('lv-mode', t.mode || '-');
    setText('hdr-mode', t.mode || '-');
    setText('lv-item', t.mission_seq ?? '-');
    setText('lv-landed', t.landed ? t.landed.replace(/_/g, ' ') : '-');
    setText('lv-alt', t.position ? fmt(t.position.relative_alt_m, 1) + ' m' : '-');
    setText('lv-speed', t.position ? fmt(t.position.speed_m_s, 1) + ' m/s' : '-');
    const b = t.battery;
    if (b) {
      setText('hdr-battery', fmt(b.voltage_v, 2) + ' V ' + fmt(b.power_w, 0) + ' W');
      state.battery.push({ wall_ms: t.wall_ms, voltage_v: b.voltage_v, current_a: b.current_a, power_w: b.power_w });
      scheduleCharts();
    }
    if (t.flight) {
      setText('lv-flight', t.flight.flight + ' ' + fmt(t.flight.t_s, 0) + ' s');
      if (state.liveFlight !== t.flight.flight) startFlight(t.flight.flight);
      if (t.flight.guard) {
        state.guard = t.flight.guard;
        renderGuard();
      }
      const p = t.flight.in_progress;
      if (p && p.kind === 'leg') {
        const existing = state.legs.get(p.index);
        if (!existing || existing.state !== 'done') {
          state.legs.set(p.index, { part: p, state: 'flying' });
          renderLegs();
        }
      }
    }
  }
  function startFlight(name) {
    state.liveFlight = name;
    state.legs = new Map();
    setText('live-flight-name', name);
    setText('live-note', '');
    state.guard = null;
    state.guardNotes = [];
    renderGuard();
    renderLegs();
  }
  // The energy guard: its view (from the telemetry) and its notes (events, or the flight's view).
  const WARN_VERDICTS = ['at_risk', 'below_reserve'];
  const WARN_KINDS = ['point_of_no_return', 'return'];
  function noteWarns(n) {
    return WARN_KINDS.includes(n.kind) || WARN_VERDICTS.includes(n.verdict);
  }
  function applyGuardNote(e) {
    if (state.liveFlight !== e.flight) startFlight(e.flight);
    state.guardNotes.push(e.note);
    renderGuard();
  }
  function renderGuard() {
    const g = state.guard;
    const notes = state.guardNotes;
    const box = $('guard');
    box.hidden = !g && !notes.length;
    if (box.hidden) return;
    const returning = (g && g.returning) || notes.some((n) => n.kind === 'return');
    const verdict = g ? g.verdict : notes[notes.length - 1].verdict;
    box.dataset.verdict = verdict;
    box.dataset.returning = returning ? 'yes' : 'no';
    setText('gd-policy', g ? '(' + g.policy + ')' : '');
    let text;
    let kind;
    if (returning) {
      text = 'RETURNING: sent home to keep the reserve';
      kind = 'warn';
    } else if (verdict === 'unmeasurable') {
      text = 'cannot judge: ' + ((g && g.reason) || 'no measurement');
      kind = 'unknown';
    } else {
      text = verdict.replace(/_/g, ' ');
      kind = WARN_VERDICTS.includes(verdict) ? 'warn' : 'ok';
    }
    const line = $('gd-verdict');
    line.textContent = text;
    line.className = 'gd-verdict ' + kind;
    box.classList.toggle('warn', kind === 'warn');
    const facts = [];
    if (g) {
      // The bar spans the pack at take-off: the reserve, the band, the projection on it.
      const full = g.pack_kj > 0 ? g.pack_kj : 1;
      const at = (kj) => Math.max(0, Math.min(100, (100 * kj) / full)) + '%';
      const [low, high] = g.left_at_landing_band_kj;
      const measured = verdict !== 'unmeasurable';
      $('gd-reserve-zone').style.width = at(g.reserve_kj);
      $('gd-band').hidden = !measured;
      $('gd-left').hidden = !measured;
      $('gd-band').style.left = at(low);
      $('gd-band').style.width = Math.max(0, parseFloat(at(high)) - parseFloat(at(low))) + '%';
      $('gd-left').style.left = at(g.left_at_landing_kj);
      $('gd-bar').setAttribute(
        'aria-label',
        'energy left at landing ' + fmt(g.left_at_landing_kj, 1) + ' kJ against the reserve ' + fmt(g.reserve_kj, 1) + ' kJ',
      );
      facts.push(
        ['Left at landing', fmt(g.left_at_landing_kj, 1) + ' kJ (' + fmt(low, 1) + ' to ' + fmt(high, 1) + ')'],
        ['Reserve', fmt(g.reserve_kj, 1) + ' kJ'],
        ['Left if home now', fmt(g.left_if_home_now_kj, 1) + ' kJ'],
        ['Correction', '\u00d7' + fmt(g.correction, 2) + ' \u00b1 ' + fmt(100 * g.correction_sd_ln, 0) + '% (' + g.parts_learned + ' parts learned)'],
        ['Pack', fmt(g.pack_kj, 1) + ' kJ at take-off, charge ' + fmt(100 * g.state_of_charge_at_takeoff, 0) + '%, capacity \u00d7' + fmt(g.capacity_ratio, 2) + ' of the label'],
        ['Drawn', fmt(g.drawn_kj, 1) + ' kJ'],
        ['Point of no return', g.point_of_no_return || '-'],
      );
    }
    $('gd-bar').hidden = !g;
    $('gd-facts').replaceChildren(...facts.flatMap(([k, v]) => [el('dt', { text: k }), el('dd', { text: v })]));
    $('gd-notes').replaceChildren(
      ...notes.map((n) =>
        el('li', { class: noteWarns(n) ? 'warn' : null, 'data-kind': n.kind, 'data-verdict': n.verdict, text: fmt(n.t_s, 0) + ' s ' + n.kind.replace(/_/g, ' ') + ': ' + n.message }),
      ),
    );
  }
  function applyPart(p) {
    if (p.kind !== 'leg') return;
    if (state.liveFlight !== p.flight) startFlight(p.flight);
    state.legs.set(p.index, { part: p, state: 'done' });
    renderLegs();
  }
  function renderLegs() {
    const rows = [...state.legs.values()].sort((a, b) => a.part.start_s - b.part.start_s);
    $('live-legs-body').replaceChildren(
      ...rows.map((r, k) => {
        const p = r.part;
        return el(
          'tr',
          { 'data-state': r.state },
          el('td', { class: 'num', text: String(k + 1) }),
          el('td', { text: p.from + ' > ' + p.to }),
          el('td', { class: 'num', text: fmt(p.predicted_kj, 3) }),
          el('td', { class: 'num', text: fmt(p.measured_kj, 3) }),
          el('td', { class: 'num', text: r.state === 'done' ? pct(p.error_pct) : '-' }),
          el('td', { class: 'num', text: fmt(p.duration_s, 1) }),
          el('td', { text: r.state === 'done' ? 'done' + (p.flags && p.flags.length ? ' (' + p.flags.join(', ') + ')' : '') : 'flying' }),
        );
      }),
    );
  }

  let chartTimer = null;
  function scheduleCharts() {
    if (chartTimer) return;
    chartTimer = setTimeout(() => {
      chartTimer = null;
      drawCharts();
    }, 500);
  }
  function drawCharts() {
    const now = state.battery.length ? state.battery[state.battery.length - 1].wall_ms : Date.now();
    state.battery = state.battery.filter((p) => p.wall_ms >= now - CHART_WINDOW_MS);
    if ($('view-live').hidden) return;
    // The time axis spans what is held: from the oldest point (at most 5 minutes back) to now.
    const from = state.battery.length ? Math.min(state.battery[0].wall_ms, now - 10000) : now - CHART_WINDOW_MS;
    $('ch-span').textContent = '(last ' + Math.round((now - from) / 1000) + ' s, wall clock)';
    drawChart('ch-voltage', 'voltage_v', 'V', 2, from, now);
    drawChart('ch-current', 'current_a', 'A', 1, from, now);
    drawChart('ch-power', 'power_w', 'W', 0, from, now);
  }
  function drawChart(id, key, unit, digits, from, now) {
    const svg = $(id);
    const NS = 'http://www.w3.org/2000/svg';
    const W = 520;
    const H = 120;
    const points = state.battery.filter((p) => p[key] !== null && p[key] !== undefined);
    const nodes = [];
    const line = (x1, y1, x2, y2) => {
      const l = document.createElementNS(NS, 'line');
      for (const [k, v] of Object.entries({ x1, y1, x2, y2, class: 'axis' })) l.setAttribute(k, v);
      return l;
    };
    nodes.push(line(78, H - 1, W, H - 1), line(78, 0, 78, H));
    $(id + '-now').textContent = points.length ? fmt(points[points.length - 1][key], digits) + ' ' + unit : '-';
    if (points.length > 1) {
      let lo = Math.min(...points.map((p) => p[key]));
      let hi = Math.max(...points.map((p) => p[key]));
      if (hi - lo < 1e-6) {
        hi += 1;
        lo -= 1;
      }
      const pad = (hi - lo) * 0.1;
      lo -= pad;
      hi += pad;
      const left = 78; // the scale's labels stand left of the line
      const x = (t) => left + ((t - from) / Math.max(1, now - from)) * (W - left);
      const y = (v) => H - ((v - lo) / (hi - lo)) * H;
      const poly = document.createElementNS(NS, 'polyline');
      poly.setAttribute('class', 'line');
      poly.setAttribute('points', points.map((p) => x(p.wall_ms).toFixed(1) + ',' + y(p[key]).toFixed(1)).join(' '));
      nodes.push(poly);
      for (const [v, yy] of [
        [hi, 14],
        [lo, H - 4],
      ]) {
        const t = document.createElementNS(NS, 'text');
        t.setAttribute('x', '4');
        t.setAttribute('y', String(yy));
        t.textContent = fmt(v, digits) + ' ' + unit;
        nodes.push(t);
      }
    }
    svg.replaceChildren(...nodes);
  }

  $('start-btn').addEventListener('click', async () => {
    const box = $('start-result');
    const button = $('start-btn');
    button.disabled = true;
    showResult(box, 'busy', 'Starting…');
    try {
      const answer = await authorizedPost('/api/vehicle/start', {});
      if (answer === null) showResult(box, 'fail', 'Not started: no token entered.');
      else if (answer.ok) {
        showResult(box, 'ok', 'Started: armed, mission running');
        box.dataset.outcome = 'started';
      } else {
        showResult(box, 'fail', failureText(answer));
        box.dataset.outcome = 'failed';
      }
    } finally {
      button.disabled = false;
    }
  });

  async function loadVehicle() {
    const [vehicle, battery] = await Promise.all([api('/api/vehicle'), api('/api/battery')]);
    if (vehicle.ok) {
      applyLink(vehicle.body.link);
      const f = vehicle.body.flight;
      if (f) {
        startFlight(f.flight);
        for (const p of f.parts || []) if (p.kind === 'leg') state.legs.set(p.index, { part: p, state: 'done' });
        state.guardNotes = f.guard_notes || [];
        renderGuard();
        renderLegs();
        if (!f.recording) setText('live-note', 'Last flight ' + f.flight + ' ended.');
      }
      applyTelemetry(vehicle.body.telemetry);
    }
    if (battery.ok) {
      state.battery = (battery.body.history || []).concat(state.battery);
      drawCharts();
    }
  }

  // ---- flights -------------------------------------------------------------------------
  async function loadFlights(select) {
    const answer = await api('/api/flights');
    const body = $('flights-body');
    if (!answer.ok) {
      body.replaceChildren(el('tr', {}, el('td', { colspan: 3, class: 'bad', text: failureText(answer) })));
      return;
    }
    state.flights = answer.body.flights || [];
    $('flights-dir').textContent = 'Log directory: ' + answer.body.dir;
    if (state.flights.length === 0) {
      body.replaceChildren(el('tr', {}, el('td', { colspan: 3, text: 'No flight recorded yet.' })));
      return;
    }
    body.replaceChildren(
      ...state.flights.map((f) =>
        el(
          'tr',
          {
            class: 'clickable' + (f.name === state.report ? ' selected' : ''),
            tabindex: 0,
            'data-name': f.name,
            onclick: () => loadReport(f.name),
            onkeydown: (e) => {
              if (e.key === 'Enter') loadReport(f.name);
            },
          },
          el('td', { text: f.name + (f.recording ? ' (recording)' : f.complete === false ? ' (incomplete)' : '') }),
          el('td', { class: 'num', text: f.legs ?? '-' }),
          el('td', { class: 'num', text: f.total ? fmt(f.total.measured_kj, 2) : '-' }),
        ),
      ),
    );
    const wanted = select || state.report || state.flights[0].name;
    loadReport(wanted);
  }

  async function loadReport(name) {
    state.report = name;
    for (const row of $('flights-body').children) row.classList.toggle('selected', row.dataset.name === name);
    const answer = await api('/api/flights/' + enc(name));
    if (state.report !== name) return;
    $('rp-title').textContent = 'Flight ' + name;
    if (!answer.ok) {
      $('rp-summary').replaceChildren(el('p', { class: 'bad', text: failureText(answer) }));
      $('report-legs').hidden = true;
      $('rp-figure').hidden = true;
      return;
    }
    const f = answer.body;
    const files = f.files || {};
    const links = [];
    if (files.tlog) links.push(el('a', { href: files.tlog, download: name + '-flight.tlog', id: 'rp-tlog', text: 'Telemetry log (.tlog)' }));
    if (files.samples) links.push(el('a', { href: files.samples, download: name + '-samples.csv', id: 'rp-csv', text: 'Samples (CSV)' }));
    if (files.report) links.push(el('a', { href: files.report, download: name + '-report.json', text: 'Report (JSON)' }));
    $('rp-files').replaceChildren(...links);
    const r = f.report;
    if (!r) {
      $('rp-summary').replaceChildren(el('p', { text: f.recording ? 'Recording: the report is written when it lands.' : 'No report for this flight.' }));
      $('report-legs').hidden = true;
    } else {
      const t = r.total || {};
      $('rp-summary').replaceChildren(
        el(
          'p',
          {},
          'Mission ' + (f.mission || '-') + ': predicted ',
          el('b', { text: fmt(t.predicted_kj, 2) + ' kJ' }),
          ', measured ',
          el('b', { text: fmt(t.measured_kj, 2) + ' kJ' }),
          ' (',
          el('b', { text: pct(t.error_pct) }),
          '), ' + fmt(t.duration_s, 0) + ' s, ',
          el('span', { class: r.complete ? 'good' : 'bad', text: r.complete ? 'complete' : 'incomplete' }),
          r.flags && r.flags.length ? '; flags: ' + r.flags.join(', ') : '',
        ),
      );
      const top = Math.max(1e-9, ...r.legs.flatMap((l) => [l.predicted_kj || 0, l.measured_kj || 0]));
      $('report-legs-body').replaceChildren(
        ...r.legs.map((l, k) =>
          el(
            'tr',
            {},
            el('td', { class: 'num', text: String(k + 1) }),
            el('td', { text: l.from + ' > ' + l.to }),
            el('td', { class: 'num', text: fmt(l.predicted_kj, 3) }),
            el('td', { class: 'num', text: fmt(l.measured_kj, 3) }),
            el('td', { class: 'num', text: pct(l.error_pct) }),
            el(
              'td',
              { class: 'bars' },
              el('div', { class: 'bar predicted', width: (100 * (l.predicted_kj || 0)) / top + '%' }),
              el('div', { class: 'bar measured', width: (100 * (l.measured_kj || 0)) / top + '%' }),
            ),
          ),
        ),
      );
      $('report-legs').hidden = false;
    }
    // A flight just begun has too little log to replay (422): its figure is drawn once it has
    // a report.
    const drawable = !(f.recording && !r);
    $('rp-figure').hidden = !drawable;
    if (drawable) {
      $('rp-plot').src = '/api/flights/' + enc(name) + '/plot.svg?complete=' + String(r ? r.complete : 'no') + '&legs=' + (r ? r.legs.length : 0);
      $('rp-plot-open').href = $('rp-plot').src;
    }
  }

  // ---- packs ---------------------------------------------------------------------------
  const estimate = (e, scale, digits, unit) => (e ? fmt(e.value * scale, digits) + (e.sd !== null && e.sd !== undefined ? ' \u00b1 ' + fmt(e.sd * scale, digits) : '') + (unit || '') : '-');
  function fadeText(p) {
    const f = p.fade_ah_per_cycle;
    if (!f) return '-';
    const ah = estimate(f, 1, 3, ' Ah');
    return p.label_capacity_ah ? ah + ' (' + fmt((100 * f.value) / p.label_capacity_ah, 2) + '%)' : ah;
  }
  // When the pack last flew (its last flight's start, UTC), else that flight's name.
  function lastFlown(p) {
    const last = (p.history || [])[(p.history || []).length - 1];
    if (last && last.started_at) return last.started_at.replace('T', ' ').replace('Z', ' UTC');
    return p.last_flight || '-';
  }
  async function loadPacks() {
    const answer = await api('/api/packs');
    const body = $('packs-body');
    if (!answer.ok) {
      body.replaceChildren(el('tr', {}, el('td', { colspan: 9, class: 'bad', text: failureText(answer) })));
      return;
    }
    state.packs = answer.body.packs || [];
    $('packs-ledger').textContent = 'Ledger: ' + answer.body.ledger + (answer.body.exists ? '' : ' (made when the first flight lands)');
    $('pack-names').replaceChildren(...state.packs.map((p) => el('option', { value: p.name })));
    if (state.packs.length === 0) {
      body.replaceChildren(el('tr', {}, el('td', { colspan: 9, text: 'No pack flown yet: name the pack when you upload a mission.' })));
      $('packs-charts').replaceChildren();
      return;
    }
    body.replaceChildren(
      ...state.packs.map((p) =>
        el(
          'tr',
          { 'data-name': p.name, class: p.warnings && p.warnings.length ? 'warn' : null },
          el('td', { text: p.name }),
          el('td', { class: 'num flights', text: String(p.flights) }),
          el('td', { class: 'num', text: fmt(p.cycles, 2) }),
          el('td', { class: 'num capacity', text: estimate(p.capacity_ratio, 100, 1, '%') }),
          el('td', { class: 'num', text: estimate(p.capacity_ah, 1, 2) + (p.label_capacity_ah ? ' of ' + fmt(p.label_capacity_ah, 2) : '') }),
          el('td', { class: 'num', text: estimate(p.internal_resistance_ohm, 1000, 1) }),
          el('td', { class: 'num', text: fadeText(p) }),
          el('td', { class: 'when', title: p.last_flight || '', text: lastFlown(p) }),
          el('td', { class: 'warnings', text: (p.warnings || []).join('; ') }),
        ),
      ),
    );
    $('packs-charts').replaceChildren(...state.packs.map(packChart));
  }
  // The capacity each flight measured (% of the label, or Ah without one) over the pack's cycles.
  function packChart(p) {
    const NS = 'http://www.w3.org/2000/svg';
    const W = 420;
    const H = 170;
    const left = 56;
    const bottom = H - 22;
    const svg = document.createElementNS(NS, 'svg');
    svg.setAttribute('viewBox', '0 0 ' + W + ' ' + H);
    svg.setAttribute('role', 'img');
    svg.setAttribute('aria-label', 'capacity of pack ' + p.name + ' over its cycles');
    const node = (tag, attrs, text) => {
      const n = document.createElementNS(NS, tag);
      for (const [k, v] of Object.entries(attrs)) n.setAttribute(k, String(v));
      if (text !== undefined) n.textContent = text;
      svg.append(n);
      return n;
    };
    const pts = (p.history || [])
      .map((h, k) => {
        const label = h.label_capacity_ah;
        const scale = label ? 100 / label : 1;
        return { x: h.cycles ?? k + 1, y: h.capacity_ah === null || h.capacity_ah === undefined ? null : h.capacity_ah * scale, sd: (h.capacity_sd_ah || 0) * scale, pct: !!label };
      })
      .filter((q) => q.y !== null && Number.isFinite(q.y));
    const unit = pts.length && pts.every((q) => q.pct) ? '%' : 'Ah';
    node('line', { x1: left, y1: bottom, x2: W - 4, y2: bottom, class: 'axis' });
    node('line', { x1: left, y1: 4, x2: left, y2: bottom, class: 'axis' });
    if (pts.length === 0) {
      node('text', { x: left + 10, y: bottom / 2 }, 'no capacity measured yet');
    } else {
      let lo = Math.min(...pts.map((q) => q.y - q.sd));
      let hi = Math.max(...pts.map((q) => q.y + q.sd));
      if (unit === '%') {
        hi = Math.max(hi, 100);
      }
      if (hi - lo < 1) {
        hi += 0.5;
        lo -= 0.5;
      }
      const pad = (hi - lo) * 0.08;
      lo -= pad;
      hi += pad;
      // From a new pack (0 cycles) to its age now.
      const x0 = Math.min(0, ...pts.map((q) => q.x));
      const x1 = Math.max(...pts.map((q) => q.x));
      const span = x1 - x0 > 1e-9 ? x1 - x0 : 1;
      const x = (v) => left + 10 + ((v - x0) / span) * (W - left - 24);
      const y = (v) => 4 + ((hi - v) / (hi - lo)) * (bottom - 8);
      if (unit === '%' && hi >= 100 && lo <= 100) node('line', { x1: left, y1: y(100), x2: W - 4, y2: y(100), class: 'label-line' });
      node('polyline', { class: 'line', points: pts.map((q) => x(q.x).toFixed(1) + ',' + y(q.y).toFixed(1)).join(' ') });
      for (const q of pts) {
        if (q.sd > 0) node('line', { x1: x(q.x), y1: y(q.y - q.sd), x2: x(q.x), y2: y(q.y + q.sd), class: 'sd' });
        node('circle', { cx: x(q.x).toFixed(1), cy: y(q.y).toFixed(1), r: 4, class: 'point' });
      }
      node('text', { x: 2, y: 16 }, fmt(hi, 1) + ' ' + unit);
      node('text', { x: 2, y: bottom - 2 }, fmt(lo, 1) + ' ' + unit);
      node('text', { x: left, y: H - 4 }, fmt(x0, 1));
      node('text', { x: W - 120, y: H - 4 }, fmt(x1, 2) + ' cycles');
    }
    return el('figure', { class: 'pack-chart', 'data-name': p.name }, svg, el('figcaption', { text: p.name + ': capacity ' + (unit === '%' ? 'of the label' : '(Ah)') + ' per flight over cycles' + (unit === '%' ? ' (dashed: the label)' : '') }));
  }

  // ---- the event stream ----------------------------------------------------------------
  let missionsTimer = null;
  function reloadMissionsSoon() {
    clearTimeout(missionsTimer);
    missionsTimer = setTimeout(loadMissions, 200);
  }
  function follow() {
    const source = new EventSource('/api/events');
    let lost = false;
    source.onopen = () => {
      $('events-state').hidden = true;
      if (lost) {
        // Back after a gap (the service restarted, the network dropped): what was missed is read again.
        lost = false;
        loadMissions();
        loadVehicle();
        loadFlights();
        loadPacks();
      }
    };
    source.onerror = () => {
      lost = true;
      $('events-state').hidden = false;
      $('events-state').textContent = 'Lost the service\u2019s event stream: reconnecting…';
    };
    source.onmessage = (message) => {
      let e;
      try {
        e = JSON.parse(message.data);
      } catch (err) {
        return;
      }
      switch (e.type) {
        case 'telemetry':
          applyTelemetry(e);
          break;
        case 'part':
          applyPart(e);
          break;
        case 'guard':
          applyGuardNote(e);
          break;
        case 'flight_started':
          startFlight(e.flight);
          setText('live-note', (e.resumed ? 'Resumed recording ' : 'Recording ') + e.flight);
          loadFlights();
          break;
        case 'flight_ended':
          for (const r of state.legs.values()) if (r.state === 'flying') r.state = 'cut off';
          if (e.report) {
            state.legs = new Map();
            for (const l of e.report.legs) state.legs.set(state.legs.size, { part: l, state: 'done' });
          }
          renderLegs();
          setText('live-note', 'Flight ' + e.flight + ' ended: its report is under Flights.');
          $('live-note').dataset.ended = e.flight;
          loadFlights(e.flight);
          // The flight is written to the ledger once its files are complete: read the packs again then.
          setTimeout(loadPacks, 1500);
          break;
        case 'recording_failed':
          setText('live-note', 'Recording ' + e.flight + ' failed: ' + e.error);
          break;
        case 'mission_planned':
        case 'mission_error':
        case 'mission_removed':
          reloadMissionsSoon();
          break;
        case 'link':
          applyLink(e);
          break;
        case 'lagged':
          loadVehicle();
          break;
        default:
          break;
      }
    };
  }

  loadMissions();
  loadVehicle();
  loadFlights();
  loadPacks();
  follow();
})();
