// rgmcad live page: shows the state the server pushes over a WebSocket (rgmcad/live/session.py)
// and sends back what the user changes. The 3D replay is the viewer's own page (/view): each new
// result is loaded into the hidden one of two frames, shown once its viewer is ready, so the
// picture never goes blank while the next one loads.
(function () {
  'use strict';
  const $ = (selector) => document.querySelector(selector);
  const ui = {
    scenario: $('#scenario'), status: $('#status'), error: $('#error'), note: $('#note'),
    frames: [$('#view-a'), $('#view-b')], outcome: $('#outcome'), fails: $('#fails'), overlaps: $('#overlaps'),
    versus: $('#versus'), layout: $('#layout'), sliders: $('#sliders'), compare: $('#compare'),
    saveName: $('#save-name'), save: $('#save'), notice: $('#notice'), events: $('#events tbody'),
    sweepName: $('#sweep-name'), sweepPoints: $('#sweep-points'), sweep: $('#sweep'),
    strip: $('#sweep-strip'), sweepStatus: $('#sweep-status'), sweepTable: $('#sweep-table tbody'),
  };
  let socket = null;
  let state = null;
  let sliderKey = '';
  let loading = 0;

  function send(message) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
  }

  function connect() {
    const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`);
    ws.addEventListener('message', (e) => render(JSON.parse(e.data)));
    ws.addEventListener('close', () => {
      ui.status.textContent = 'disconnected: is rgmcad live still running? Trying again...';
      document.body.dataset.connected = '0';
      setTimeout(connect, 1000);
    });
    ws.addEventListener('open', () => { document.body.dataset.connected = '1'; });
    socket = ws;
  }

  function make(tag, text, className) {
    const node = document.createElement(tag);
    if (text !== undefined) node.textContent = text;
    if (className) node.className = className;
    return node;
  }

  function fmt(value, unit) {
    return `${Number(value).toFixed(2)} ${unit}`;
  }

  function options(select, names, selected, blank) {
    const wanted = (blank ? [''] : []).concat(names);
    const have = [...select.options].map((o) => o.value);
    if (wanted.join('\n') !== have.join('\n')) {
      select.replaceChildren(...wanted.map((n) => { const o = make('option', n || '(none)'); o.value = n; return o; }));
    }
    select.value = selected || '';
  }

  function sliders(free) {
    const key = free.map((f) => `${f.name}|${f.low}|${f.high}|${f.unit}`).join(';');
    if (key !== sliderKey) {
      sliderKey = key;
      ui.sliders.replaceChildren(...free.map((f) => {
        const box = make('div', undefined, 'slider');
        box.dataset.name = f.name;
        const label = make('label');
        const value = make('span', '', 'value');
        label.append(make('span', f.name), value);
        const range = make('input');
        Object.assign(range, { type: 'range', min: f.low, max: f.high, step: 'any' });
        range.setAttribute('aria-label', `${f.name} (${f.unit})`);
        const number = make('input');
        Object.assign(number, { type: 'number', step: 'any' });
        number.setAttribute('aria-label', `${f.name} value (${f.unit})`);
        range.addEventListener('input', () => { value.textContent = fmt(range.value, f.unit); });
        const set = (v) => send({ type: 'set', name: f.name, value: Number(v) });
        range.addEventListener('change', () => set(range.value));
        number.addEventListener('change', () => { if (number.value !== '') set(number.value); });
        box.append(label, range, number);
        return box;
      }));
      options(ui.sweepName, free.map((f) => f.name), ui.sweepName.value || (free[0] || {}).name);
    }
    for (const f of free) {
      const box = ui.sliders.querySelector(`[data-name="${CSS.escape(f.name)}"]`);
      const [range, number] = box.querySelectorAll('input');
      if (document.activeElement !== range) range.value = f.value;
      if (document.activeElement !== number) number.value = Number(f.value.toFixed(4));
      box.querySelector('.value').textContent = fmt(f.value, f.unit);
      box.querySelector('.value').classList.toggle('changed', Boolean(f.changed));
    }
  }

  function events(main) {
    ui.events.replaceChildren(...(main ? main.events : []).map((e) => {
      const row = make('tr');
      row.dataset.event = e.name;
      row.dataset.state = e.state;
      row.append(make('td', e.name), make('td', e.state, e.state),
        make('td', e.time === null ? '' : e.time.toFixed(3)));
      return row;
    }));
  }

  function result(s) {
    const main = s.main;
    ui.outcome.textContent = main ? main.outcome : '...';
    ui.outcome.className = `outcome ${main ? main.outcome : ''}`;
    ui.outcome.dataset.outcome = main ? main.outcome : '';
    ui.fails.textContent = main && main.fails_at ? `fails at ${main.fails_at}` : '';
    ui.overlaps.replaceChildren(...(main ? main.overlaps : []).map((o) =>
      make('li', `${o.first} and ${o.second} overlap by ${o.depth_mm.toFixed(2)} mm`)));
    const other = s.compare;
    ui.versus.hidden = !other;
    if (other) {
      ui.versus.textContent = `A (left): ${main.outcome}; B (right, ${other.layout}): ${other.outcome}` +
        (other.fails_at ? `, fails at ${other.fails_at}` : '');
    }
  }

  function sweep(s) {
    if (!s) return;
    const unit = s.unit;
    ui.strip.replaceChildren(...s.points.map((p) => {
      const cell = make('button', '', p.outcome);
      cell.title = `${s.name} = ${fmt(p.value, unit)}: ${p.outcome}` +
        (p.fails_at ? ` (fails at ${p.fails_at})` : '') + (p.overlap ? ` (${p.overlap})` : '');
      cell.dataset.value = p.value;
      cell.dataset.outcome = p.outcome;
      cell.addEventListener('click', () => send({ type: 'set', name: s.name, value: p.value }));
      return cell;
    }));
    ui.sweepTable.replaceChildren(...s.points.map((p) => {
      const row = make('tr');
      row.append(make('td', fmt(p.value, unit)), make('td', p.outcome, p.outcome),
        make('td', p.fails_at || p.overlap || ''));
      return row;
    }));
    ui.sweepStatus.textContent = s.stopped || `${s.name}: ${s.points.length} of ${s.total} points` +
      (s.done ? ', done' : '...');
    document.body.dataset.sweep = s.done ? 'done' : 'running';
  }

  // The next picture keeps the camera, speed, loop and names the user left on the last one,
  // as long as it shows the same kind of scene (one layout, or two side by side); it plays
  // from its start, since it is a new run.
  let shownKind = '';
  function carryView(from, to, kind) {
    const old = from && from !== to && from.contentWindow && from.contentWindow.rgmcadViewer;
    const next = to.contentWindow && to.contentWindow.rgmcadViewer;
    if (old && next && next.setView && kind === shownKind) next.setView(old.view);
    shownKind = kind;
  }

  // the frame's page is ready once the viewer says so (or it has no viewer: the waiting page)
  function watchFrame(frame, version, kind) {
    const check = () => {
      if (version !== loading) return;  // a newer result is on its way
      const doc = frame.contentDocument;
      const root = doc && doc.getElementById('rgmcad-replay');
      const plain = doc && doc.readyState === 'complete' && !root && !doc.getElementById('rgmcad-replay-data');
      if (plain || (root && (root.dataset.ready === '1' || root.dataset.error))) {
        const front = ui.frames.find((f) => f.classList.contains('front'));
        carryView(front, frame, kind);
        frame.classList.add('front');
        if (front !== frame) {
          front.classList.remove('front');
          front.src = 'about:blank';  // its 3D view goes with it
        }
        document.body.dataset.picture = String(version);
      } else {
        setTimeout(check, 20);
      }
    };
    check();
  }

  function show(version) {
    loading = version;
    const front = ui.frames.find((f) => f.classList.contains('front'));
    const back = ui.frames.find((f) => f !== front);
    const kind = state && state.compare ? `beside ${state.compare.layout}` : 'one';
    back.onload = () => { if (back.src.endsWith(`v=${version}`)) watchFrame(back, version, kind); };
    back.src = `/view?v=${version}`;
  }

  function render(s) {
    state = s;
    const info = s.info || { free: [], layouts: [] };
    ui.scenario.textContent = info.scenario || '';
    document.body.dataset.busy = s.busy ? '1' : '0';
    document.body.dataset.generation = String(s.generation || 0);
    ui.status.textContent = s.busy ? 'simulating...' :
      (s.took !== undefined ? `up to date: ${s.took.toFixed(2)} s from the change to the result` : '');
    ui.error.hidden = !s.error;
    ui.error.textContent = s.error ? s.error.text + (s.error.line ? ` (line ${s.error.line})` : '') : '';
    document.body.dataset.stale = s.error ? '1' : '0';
    ui.note.hidden = !s.note;
    ui.note.textContent = s.note || '';
    if (s.notice) ui.notice.textContent = s.notice;
    result(s);
    sliders(info.free);
    options(ui.layout, s.layouts || info.layouts, s.layout);
    options(ui.compare, s.layouts || info.layouts, s.compare_layout, true);
    events(s.main);
    sweep(s.sweep);
    if (s.view !== Number(document.body.dataset.view)) {
      document.body.dataset.view = String(s.view);
      show(s.view);
    }
  }

  ui.layout.addEventListener('change', () => send({ type: 'layout', name: ui.layout.value }));
  ui.compare.addEventListener('change', () => send({ type: 'compare', name: ui.compare.value || null }));
  ui.save.addEventListener('click', () => send({ type: 'save', name: ui.saveName.value.trim() }));
  ui.sweep.addEventListener('click', () => send({
    type: 'sweep', name: ui.sweepName.value, points: Number(ui.sweepPoints.value) || 21 }));
  window.rgmcadLive = { state: () => state, send };
  connect();
}());
