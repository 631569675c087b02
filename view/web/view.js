// fogmap live map viewer.
//
// Subscribes to the view server's Server-Sent-Events stream (`events`, relative to this page)
// and draws the latest global map and tracks as a top view on a canvas, with a side panel of
// text. The server sends `config` first on each connection, then the latest `status`, `map` and
// `tracks` as they come; `status` is repeated every second as a heartbeat.
//
// Frame: metres in the common ground frame, x east (drawn to the right), y north (drawn
// upward); angles in degrees, counter-clockwise from +x.
//
// The page never polls: everything it shows arrives on the one EventSource. Drawing happens
// synchronously in each event handler (unless paused), so the page is current when a handler
// returns. Malformed event data is counted and ignored; no handler ever throws.

'use strict';

(() => {
  // ---- Constants ---------------------------------------------------------------------------

  // Colour of each object class; `unknown` is used for a null or unrecognised class.
  const CLASS_COLORS = Object.freeze({
    person: '#ffb020',
    car: '#4da3ff',
    truck_or_bus: '#b88cff',
    cyclist: '#ff6ec7',
    pole: '#d0d7e2',
    other: '#e6d36e',
    unknown: '#8b95a7',
  });

  const LIDAR_COLOR = '#35d8ff';
  const CAMERA_COLOR = '#f4f4f4';
  const FENCE_OCCUPIED = 'rgba(255, 80, 80, 0.95)';
  const FENCE_OCCUPIED_FILL = 'rgba(255, 60, 60, 0.22)';
  const FENCE_FREE = '#3fbf6a';
  const FENCE_UNKNOWN = '#7a8496';
  const BACKGROUND = '#11151c';

  const MIN_SCALE = 0.2;          // pixels per metre, fully zoomed out
  const MAX_SCALE = 4000;         // pixels per metre, fully zoomed in
  const MIN_FIT_SPAN_M = 10;      // Fit never zooms in closer than this many metres across
  const CLICK_SLOP_PX = 4;        // pointer travel below which a press counts as a click
  const HIT_TOLERANCE_PX = 4;     // shapes are this much larger for clicking than drawn
  const MAX_LATENCIES = 500;      // latencies kept in the test state
  const WATCHDOG_MS = 8000;       // no event (not even the 1 s heartbeat) for this long: reconnect
  const RECONNECT_MS = 2000;      // delay before re-creating an EventSource the browser gave up on
  const LABEL_FONT = '12px system-ui, "DejaVu Sans", sans-serif';
  const LABEL_FONT_BOLD = 'bold 12px system-ui, "DejaVu Sans", sans-serif';

  // ---- DOM ---------------------------------------------------------------------------------

  const $ = (id) => document.getElementById(id);
  const canvas = $('map');
  const ctx = canvas.getContext('2d');
  const dom = {
    banner: $('banner'),
    pause: $('pause'),
    fit: $('fit'),
    cursor: $('cursor'),
    topology: $('topology'),
    connSse: $('conn-sse'),
    connRoot: $('conn-root'),
    connRootDetail: $('conn-root-detail'),
    rowTracker: $('row-tracker'),
    connTracker: $('conn-tracker'),
    connTrackerDetail: $('conn-tracker-detail'),
    connExtra: $('conn-extra'),
    pausedTag: $('paused-tag'),
    epoch: $('m-epoch'),
    revision: $('m-revision'),
    objects: $('m-objects'),
    tracks: $('m-tracks'),
    latency: $('m-latency'),
    rate: $('m-rate'),
    details: $('details'),
    detailsHint: $('details-hint'),
    nodes: document.querySelector('#nodes tbody'),
    fences: $('fences'),
    legend: $('legend'),
    state: $('fogmap-state'),
  };

  // ---- Page state --------------------------------------------------------------------------

  const S = {
    es: null,                     // the current EventSource
    sse: 'connecting',            // 'connecting' | 'open' | 'lost'
    watchdog: 0,                  // setTimeout handle of the stall watchdog
    lastEventAt: 0,               // Date.now() of the last event or connection opening
    config: null,
    status: null,
    latest: { map: null, tracks: null },   // newest data received
    shown: { map: null, tracks: null },    // data on screen (frozen while paused)
    mapsReceived: 0,
    tracksReceived: 0,
    malformed: 0,
    firstTracks: null,            // [{id, x, y}] of the first non-empty track list
    latencies: [],                // ms from a map's publication to its drawing
    mapArrivals: [],              // arrival times (ms) of recent maps, for the rate
    firstMapAt: null,             // arrival time (ms) of the first map
    paused: false,
    selectedId: null,             // id of the selected object, or null
    selectedLast: null,           // last seen copy of the selected object
    selectedLastEpoch: null,      // epoch in which it was last seen
    view: { cx: 0, cy: 0, scale: 20 },     // world point at the canvas centre; pixels per metre
    viewTouched: false,           // the user panned or zoomed: stop fitting automatically
    fittedWithObjects: false,     // the automatic fit has already seen objects
    width: 1,                     // canvas size in CSS pixels
    height: 1,
  };

  // ---- Validation of event data ------------------------------------------------------------
  //
  // Each parser turns the decoded JSON of one event into a clean object or throws Malformed.
  // Optional fields that are absent get a default; present fields of the wrong type are errors.

  class Malformed extends Error {}

  const fail = (what) => { throw new Malformed(what); };
  const isObject = (v) => v !== null && typeof v === 'object' && !Array.isArray(v);

  function obj(v, what) {
    if (!isObject(v)) fail(`${what}: expected an object`);
    return v;
  }

  function arr(v, what, fallback) {
    if (v === undefined && fallback !== undefined) return fallback;
    if (!Array.isArray(v)) fail(`${what}: expected an array`);
    return v;
  }

  function num(v, what, fallback) {
    if (v === undefined && fallback !== undefined) return fallback;
    if (typeof v !== 'number' || !Number.isFinite(v)) fail(`${what}: expected a number`);
    return v;
  }

  function numOrNull(v, what) {
    return v === null || v === undefined ? null : num(v, what);
  }

  function str(v, what, fallback) {
    if ((v === undefined || v === null) && fallback !== undefined) return fallback;
    if (typeof v !== 'string') fail(`${what}: expected a string`);
    return v;
  }

  function strOrNull(v, what) {
    return v === null || v === undefined ? null : str(v, what);
  }

  function bool(v, what, fallback) {
    if (v === undefined && fallback !== undefined) return fallback;
    if (typeof v !== 'boolean') fail(`${what}: expected true or false`);
    return v;
  }

  // [x, y] or [x, y, z] -> [x, y, z] (z defaults to 0).
  function point(v, what) {
    arr(v, what);
    if (v.length < 2) fail(`${what}: expected [x, y] or [x, y, z]`);
    return [num(v[0], what), num(v[1], what), v.length > 2 ? num(v[2], what) : 0];
  }

  function parseBox(v, what) {
    obj(v, what);
    return {
      min: point(v.min, `${what}.min`),
      max: point(v.max, `${what}.max`),
    };
  }

  function parseConfig(d) {
    obj(d, 'config');
    return {
      topology: str(d.topology, 'topology', ''),
      hasTracker: bool(d.has_tracker, 'has_tracker', false),
      sensors: arr(d.sensors, 'sensors', []).map((s, i) => {
        const w = `sensors[${i}]`;
        obj(s, w);
        return {
          name: str(s.name, `${w}.name`, ''),
          kind: str(s.kind, `${w}.kind`, 'lidar'),
          x: num(s.x, `${w}.x`),
          y: num(s.y, `${w}.y`),
          z: numOrNull(s.z, `${w}.z`),
          heading: numOrNull(s.heading_deg, `${w}.heading_deg`),
        };
      }),
      geofences: arr(d.geofences, 'geofences', []).map((g, i) => {
        const w = `geofences[${i}]`;
        obj(g, w);
        return { name: str(g.name, `${w}.name`, ''), ...parseBox(g, w) };
      }),
      nodes: arr(d.nodes, 'nodes', []).map((n, i) => {
        const w = `nodes[${i}]`;
        obj(n, w);
        return {
          id: num(n.id, `${w}.id`),
          name: str(n.name, `${w}.name`, ''),
          role: str(n.role, `${w}.role`, ''),
        };
      }),
    };
  }

  function parseObject(o, w) {
    obj(o, w);
    let box = null;
    if (o.box !== null && o.box !== undefined) {
      const b = obj(o.box, `${w}.box`);
      box = {
        cx: num(b.cx, `${w}.box.cx`),
        cy: num(b.cy, `${w}.box.cy`),
        length: num(b.length, `${w}.box.length`),
        width: num(b.width, `${w}.box.width`),
        yaw: num(b.yaw_deg, `${w}.box.yaw_deg`, 0),
        zmin: numOrNull(b.zmin, `${w}.box.zmin`),
        zmax: numOrNull(b.zmax, `${w}.box.zmax`),
      };
    }
    const extent = o.extent === null || o.extent === undefined ? null : parseBox(o.extent, `${w}.extent`);
    return {
      id: num(o.id, `${w}.id`),
      points: num(o.points, `${w}.points`, 0),
      sensors: arr(o.sensors, `${w}.sensors`, []).map((s) => str(s, `${w}.sensors[]`)),
      cls: strOrNull(o.class, `${w}.class`),
      confidence: numOrNull(o.confidence, `${w}.confidence`),
      box,
      extent,
      ellipses: arr(o.ellipses, `${w}.ellipses`, []).map((e, j) => {
        const we = `${w}.ellipses[${j}]`;
        obj(e, we);
        return {
          cx: num(e.cx, `${we}.cx`),
          cy: num(e.cy, `${we}.cy`),
          a: Math.abs(num(e.a, `${we}.a`)),
          b: Math.abs(num(e.b, `${we}.b`)),
          angle: num(e.angle_deg, `${we}.angle_deg`, 0),
          sensor: strOrNull(e.sensor, `${we}.sensor`),
          points: numOrNull(e.points, `${we}.points`),
        };
      }),
    };
  }

  function parseMap(d) {
    obj(d, 'map');
    return {
      epoch: num(d.epoch, 'epoch'),
      revision: num(d.revision, 'revision', 0),
      late: bool(d.late, 'late', false),
      publishedMs: numOrNull(d.published_ms, 'published_ms'),
      objects: arr(d.objects, 'objects').map((o, i) => parseObject(o, `objects[${i}]`)),
      geofences: arr(d.geofences, 'geofences', []).map((g, i) => {
        const w = `geofences[${i}]`;
        obj(g, w);
        return {
          name: str(g.name, `${w}.name`, ''),
          occupied: bool(g.occupied, `${w}.occupied`),
          objects: arr(g.objects, `${w}.objects`, []).map((id) => num(id, `${w}.objects[]`)),
        };
      }),
      nodes: arr(d.nodes, 'nodes', []).map((n, i) => {
        const w = `nodes[${i}]`;
        obj(n, w);
        return {
          id: numOrNull(n.id, `${w}.id`),
          name: str(n.name, `${w}.name`, ''),
          missing: bool(n.missing, `${w}.missing`, false),
          lastEpoch: numOrNull(n.last_epoch, `${w}.last_epoch`),
        };
      }),
    };
  }

  function parseTracks(d) {
    obj(d, 'tracks');
    return {
      publishedMs: numOrNull(d.published_ms, 'published_ms'),
      lidarMs: numOrNull(d.lidar_ms, 'lidar_ms'),
      tracks: arr(d.tracks, 'tracks').map((t, i) => {
        const w = `tracks[${i}]`;
        obj(t, w);
        return {
          id: num(t.id, `${w}.id`),
          label: strOrNull(t.label, `${w}.label`),
          state: strOrNull(t.state, `${w}.state`),
          x: num(t.x, `${w}.x`),
          y: num(t.y, `${w}.y`),
          vx: numOrNull(t.vx, `${w}.vx`) ?? 0,
          vy: numOrNull(t.vy, `${w}.vy`) ?? 0,
          heading: numOrNull(t.heading_deg, `${w}.heading_deg`),
          camera: bool(t.camera, `${w}.camera`, false),
          sigma: numOrNull(t.sigma_m, `${w}.sigma_m`),
          trail: arr(t.trail, `${w}.trail`, []).map((p) => point(p, `${w}.trail[]`)),
        };
      }),
    };
  }

  function parseLink(v, what) {
    obj(v, what);
    return {
      connected: bool(v.connected, `${what}.connected`),
      target: str(v.target, `${what}.target`, ''),
      detail: str(v.detail, `${what}.detail`, ''),
    };
  }

  function parseStatus(d) {
    obj(d, 'status');
    return {
      root: parseLink(d.root, 'root'),
      tracker: d.tracker === null || d.tracker === undefined ? null : parseLink(d.tracker, 'tracker'),
      skippedEvents: num(d.skipped_events, 'skipped_events', 0),
      serverMs: numOrNull(d.server_ms, 'server_ms'),
    };
  }

  // ---- Event handlers ----------------------------------------------------------------------

  function onConfig(cfg) {
    S.config = cfg;
    if (!S.viewTouched) fitView();
    if (!S.paused) render();
  }

  // The connection part of the panel and the banner follow in afterEvent().
  function onStatus(st) {
    S.status = st;
  }

  function onMap(map) {
    S.latest.map = map;
    S.mapsReceived += 1;
    S.mapArrivals.push(Date.now());
    if (S.firstMapAt === null) S.firstMapAt = Date.now();

    if (!S.paused) {
      S.shown.map = map;
      if (!S.viewTouched && !S.fittedWithObjects && map.objects.length > 0) {
        S.fittedWithObjects = true;
        fitView();
      }
      render();
    }
    // Measured once the map is on screen (while paused: once it has been taken in).
    if (map.publishedMs !== null) {
      S.latencies.push(Date.now() - map.publishedMs);
      if (S.latencies.length > MAX_LATENCIES) S.latencies.splice(0, S.latencies.length - MAX_LATENCIES);
    }
  }

  function onTracks(tr) {
    S.latest.tracks = tr;
    S.tracksReceived += 1;
    if (S.firstTracks === null && tr.tracks.length > 0) {
      S.firstTracks = tr.tracks.map((t) => ({ id: t.id, x: t.x, y: t.y }));
    }
    if (!S.paused) {
      S.shown.tracks = tr;
      render();
    }
  }

  const HANDLERS = {
    config: { parse: parseConfig, apply: onConfig },
    status: { parse: parseStatus, apply: onStatus },
    map: { parse: parseMap, apply: onMap },
    tracks: { parse: parseTracks, apply: onTracks },
  };

  // ---- Connection to the view server -------------------------------------------------------

  function connect() {
    const es = new EventSource('events');
    S.es = es;
    S.sse = S.sse === 'lost' ? 'lost' : 'connecting';

    es.onopen = () => {
      if (es !== S.es) return;
      markOpen();
      afterEvent();
    };

    es.onerror = () => {
      if (es !== S.es) return;
      // CONNECTING: the browser retries by itself. CLOSED: it gave up (e.g. an HTTP error), so
      // a fresh EventSource is made after a pause.
      S.sse = 'lost';
      clearTimeout(S.watchdog);
      if (es.readyState === EventSource.CLOSED) setTimeout(() => { if (es === S.es) connect(); }, RECONNECT_MS);
      afterEvent();
    };

    for (const [name, handler] of Object.entries(HANDLERS)) {
      es.addEventListener(name, (ev) => {
        if (es !== S.es) return;   // a late event of a connection already replaced
        dispatch(handler, ev);
      });
    }
  }

  function markOpen() {
    S.sse = 'open';
    armWatchdog();
  }

  // A connection that stays open but carries nothing (not even the heartbeat) is stale.
  function armWatchdog() {
    S.lastEventAt = Date.now();
    clearTimeout(S.watchdog);
    S.watchdog = setTimeout(() => {
      if (S.sse !== 'open' || Date.now() - S.lastEventAt < WATCHDOG_MS) return;
      console.warn('fogmap view: no event for %d ms; reconnecting', WATCHDOG_MS);
      S.es.close();
      S.sse = 'lost';
      afterEvent();
      connect();
    }, WATCHDOG_MS);
  }

  function dispatch(handler, ev) {
    try {
      markOpen();
      let data;
      try {
        data = handler.parse(JSON.parse(ev.data));
      } catch (err) {
        S.malformed += 1;
        console.warn(`fogmap view: ignoring malformed "${ev.type}" event:`, err.message);
        return;
      }
      handler.apply(data);
    } catch (err) {
      console.error(`fogmap view: error while handling a "${ev.type}" event`, err);
    } finally {
      afterEvent();
    }
  }

  // Runs after every event and connection change: live parts of the panel and the test state.
  function afterEvent() {
    try {
      renderConnections();
      renderLatency();
      publishState();
    } catch (err) {
      console.error('fogmap view: error while updating the page', err);
    }
  }

  // ---- Test state --------------------------------------------------------------------------

  function trackerConnected() {
    if (S.status) return S.status.tracker ? S.status.tracker.connected : null;
    return S.config && S.config.hasTracker ? false : null;
  }

  function publishState() {
    const map = S.shown.map;
    const tracks = S.shown.tracks ? S.shown.tracks.tracks : [];
    const state = {
      sse_connected: S.sse === 'open',
      root_connected: S.status ? S.status.root.connected : false,
      tracker_connected: trackerConnected(),
      maps_received: S.mapsReceived,
      tracks_received: S.tracksReceived,
      epoch: map ? map.epoch : null,
      objects_drawn: map ? map.objects.length : 0,
      tracks_drawn: tracks.length,
      object_ids: map ? map.objects.map((o) => o.id) : [],
      tracks: tracks.map((t) => ({ id: t.id, x: t.x, y: t.y })),
      first_tracks: S.firstTracks || [],
      latencies_ms: S.latencies.slice(),
      paused: S.paused,
      banner: bannerText(),
      malformed_events: S.malformed,
    };
    window.fogmapState = state;
    dom.state.textContent = JSON.stringify(state);
  }

  // ---- View transform ----------------------------------------------------------------------

  const toScreenX = (x) => S.width / 2 + (x - S.view.cx) * S.view.scale;
  const toScreenY = (y) => S.height / 2 - (y - S.view.cy) * S.view.scale;
  const toWorldX = (sx) => S.view.cx + (sx - S.width / 2) / S.view.scale;
  const toWorldY = (sy) => S.view.cy - (sy - S.height / 2) / S.view.scale;
  const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
  const rad = (deg) => (deg * Math.PI) / 180;

  // Matches the canvas backing store to its on-screen size and the device pixel ratio.
  function measure() {
    const r = canvas.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    S.width = Math.max(1, r.width);
    S.height = Math.max(1, r.height);
    const w = Math.max(1, Math.round(S.width * dpr));
    const h = Math.max(1, Math.round(S.height * dpr));
    if (canvas.width !== w || canvas.height !== h) {
      canvas.width = w;
      canvas.height = h;
    }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  }

  // Fits the sensors and the objects on screen (or geofences, or 40 m around the origin).
  function fitView() {
    measure();
    const b = { minX: Infinity, minY: Infinity, maxX: -Infinity, maxY: -Infinity };
    const add = (x, y) => {
      b.minX = Math.min(b.minX, x); b.maxX = Math.max(b.maxX, x);
      b.minY = Math.min(b.minY, y); b.maxY = Math.max(b.maxY, y);
    };
    if (S.config) for (const s of S.config.sensors) add(s.x, s.y);
    if (S.shown.map) {
      for (const o of S.shown.map.objects) {
        for (const [x, y] of objectOutline(o)) add(x, y);
      }
    }
    if (!Number.isFinite(b.minX) && S.config) {
      for (const g of S.config.geofences) { add(g.min[0], g.min[1]); add(g.max[0], g.max[1]); }
    }
    if (!Number.isFinite(b.minX)) { add(-20, -20); add(20, 20); }

    const spanX = Math.max(b.maxX - b.minX, MIN_FIT_SPAN_M);
    const spanY = Math.max(b.maxY - b.minY, MIN_FIT_SPAN_M);
    S.view.cx = (b.minX + b.maxX) / 2;
    S.view.cy = (b.minY + b.maxY) / 2;
    S.view.scale = clamp(Math.min(S.width / (spanX * 1.25), S.height / (spanY * 1.25)), MIN_SCALE, MAX_SCALE);
  }

  // Corner points (x, y) that bound an object: its extent, box corners and ellipse boxes.
  function objectOutline(o) {
    const pts = [];
    if (o.extent) pts.push([o.extent.min[0], o.extent.min[1]], [o.extent.max[0], o.extent.max[1]]);
    if (o.box) pts.push(...boxCorners(o.box));
    for (const e of o.ellipses) {
      const r = Math.max(e.a, e.b);
      pts.push([e.cx - r, e.cy - r], [e.cx + r, e.cy + r]);
    }
    return pts;
  }

  function boxCorners(box) {
    const c = Math.cos(rad(box.yaw));
    const s = Math.sin(rad(box.yaw));
    const hl = box.length / 2;
    const hw = box.width / 2;
    return [[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]].map(([u, v]) => [
      box.cx + u * c - v * s,
      box.cy + u * s + v * c,
    ]);
  }

  // The largest round length (1, 2 or 5 times a power of ten) not above `m`.
  function roundLengthBelow(m) {
    const p = 10 ** Math.floor(Math.log10(m));
    for (const f of [5, 2, 1]) if (f * p <= m) return Number((f * p).toPrecision(3));
    return Number(p.toPrecision(3));
  }

  function formatLength(m) {
    return m >= 1000 ? `${Number((m / 1000).toPrecision(3))} km` : `${m} m`;
  }

  // ---- Drawing -----------------------------------------------------------------------------

  // Draws the canvas and the map-derived panel from the shown state.
  function render() {
    drawMap();
    renderMapPanel();
  }

  function drawMap() {
    measure();
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, S.width, S.height);
    ctx.lineJoin = 'round';
    ctx.lineCap = 'round';

    drawGrid();
    if (S.config) drawGeofences();
    if (S.shown.map) drawObjects(S.shown.map.objects);
    if (S.shown.tracks) drawTracks(S.shown.tracks.tracks);
    if (S.config) drawSensors();
    drawScaleBar();
    if (S.paused) drawPausedMark();
  }

  function drawGrid() {
    const step = roundLengthBelow(110 / S.view.scale);
    const x0 = Math.floor(toWorldX(0) / step) * step;
    const x1 = toWorldX(S.width);
    const y0 = Math.floor(toWorldY(S.height) / step) * step;
    const y1 = toWorldY(0);

    ctx.lineWidth = 1;
    ctx.strokeStyle = 'rgba(255, 255, 255, 0.06)';
    ctx.beginPath();
    for (let x = x0; x <= x1; x += step) {
      const sx = Math.round(toScreenX(x)) + 0.5;
      ctx.moveTo(sx, 0); ctx.lineTo(sx, S.height);
    }
    for (let y = y0; y <= y1; y += step) {
      const sy = Math.round(toScreenY(y)) + 0.5;
      ctx.moveTo(0, sy); ctx.lineTo(S.width, sy);
    }
    ctx.stroke();

    // The axes through the origin, a little brighter.
    ctx.strokeStyle = 'rgba(255, 255, 255, 0.16)';
    ctx.beginPath();
    const ox = Math.round(toScreenX(0)) + 0.5;
    const oy = Math.round(toScreenY(0)) + 0.5;
    ctx.moveTo(ox, 0); ctx.lineTo(ox, S.height);
    ctx.moveTo(0, oy); ctx.lineTo(S.width, oy);
    ctx.stroke();
  }

  function drawScaleBar() {
    const len = roundLengthBelow(200 / S.view.scale);
    const px = len * S.view.scale;
    const x = 16;
    const y = S.height - 22;

    ctx.strokeStyle = '#e6e9ef';
    ctx.lineWidth = 2;
    ctx.lineCap = 'butt';
    ctx.beginPath();
    ctx.moveTo(x, y - 5); ctx.lineTo(x, y); ctx.lineTo(x + px, y); ctx.lineTo(x + px, y - 5);
    ctx.stroke();
    ctx.lineCap = 'round';
    label(formatLength(len), x + px / 2, y - 8, '#e6e9ef', 'center', 'bottom');

    // North arrow beside the scale bar: y is drawn upward.
    const nx = x + px + 28;
    ctx.fillStyle = '#e6e9ef';
    ctx.beginPath();
    ctx.moveTo(nx, y - 22); ctx.lineTo(nx - 5, y - 8); ctx.lineTo(nx + 5, y - 8);
    ctx.closePath();
    ctx.fill();
    label('N', nx, y - 6, '#e6e9ef', 'center', 'top');
  }

  function drawPausedMark() {
    const map = S.shown.map;
    const text = map ? `PAUSED — epoch ${map.epoch}` : 'PAUSED';
    ctx.font = LABEL_FONT_BOLD;
    const w = ctx.measureText(text).width + 16;
    ctx.fillStyle = 'rgba(255, 176, 32, 0.92)';
    ctx.fillRect(S.width - w - 10, 10, w, 22);
    ctx.fillStyle = '#1a1200';
    ctx.textAlign = 'left';
    ctx.textBaseline = 'middle';
    ctx.fillText(text, S.width - w - 2, 21);
  }

  // Text with a dark halo, readable on any part of the map. Left-aligned text that starts on
  // screen but would run off the right edge is moved left to stay readable.
  function label(text, x, y, color, align = 'left', baseline = 'middle', font = LABEL_FONT) {
    ctx.font = font;
    if (align === 'left' && x >= 0 && x < S.width) {
      x = Math.max(2, Math.min(x, S.width - ctx.measureText(text).width - 4));
    }
    ctx.textAlign = align;
    ctx.textBaseline = baseline;
    ctx.lineWidth = 3;
    ctx.strokeStyle = 'rgba(10, 13, 18, 0.85)';
    ctx.strokeText(text, x, y);
    ctx.fillStyle = color;
    ctx.fillText(text, x, y);
  }

  function classColor(cls) {
    return cls !== null && Object.hasOwn(CLASS_COLORS, cls) ? CLASS_COLORS[cls] : CLASS_COLORS.unknown;
  }

  function fenceStates() {
    const states = new Map();
    if (S.shown.map) for (const g of S.shown.map.geofences) states.set(g.name, g);
    return states;
  }

  function drawGeofences() {
    const states = fenceStates();
    for (const g of S.config.geofences) {
      const x0 = toScreenX(Math.min(g.min[0], g.max[0]));
      const x1 = toScreenX(Math.max(g.min[0], g.max[0]));
      const y0 = toScreenY(Math.max(g.min[1], g.max[1]));
      const y1 = toScreenY(Math.min(g.min[1], g.max[1]));
      const st = states.get(g.name);
      let color = FENCE_UNKNOWN;
      ctx.lineWidth = 1.5;
      if (st && st.occupied) {
        color = FENCE_OCCUPIED;
        ctx.fillStyle = FENCE_OCCUPIED_FILL;
        ctx.fillRect(x0, y0, x1 - x0, y1 - y0);
        ctx.setLineDash([]);
      } else {
        if (st) color = FENCE_FREE;
        ctx.setLineDash([6, 4]);
      }
      ctx.strokeStyle = color;
      ctx.strokeRect(x0, y0, x1 - x0, y1 - y0);
      ctx.setLineDash([]);
      const state = st ? (st.occupied ? ' (occupied)' : '') : '';
      label(g.name + state, x0 + 4, y0 + 4, color, 'left', 'top');
    }
  }

  function drawObjects(objects) {
    for (const o of objects) {
      const color = classColor(o.cls);
      const selected = o.id === S.selectedId;

      for (const e of o.ellipses) {
        ctx.beginPath();
        ctx.ellipse(toScreenX(e.cx), toScreenY(e.cy),
          Math.max(e.a * S.view.scale, 2), Math.max(e.b * S.view.scale, 2),
          -rad(e.angle), 0, 2 * Math.PI);
        ctx.globalAlpha = 0.12;
        ctx.fillStyle = color;
        ctx.fill();
        ctx.globalAlpha = 0.9;
        ctx.strokeStyle = color;
        ctx.lineWidth = selected ? 2 : 1.25;
        ctx.stroke();
        ctx.globalAlpha = 1;
      }

      if (o.box) {
        ctx.beginPath();
        boxCorners(o.box).forEach(([x, y], i) => {
          if (i === 0) ctx.moveTo(toScreenX(x), toScreenY(y));
          else ctx.lineTo(toScreenX(x), toScreenY(y));
        });
        ctx.closePath();
        ctx.strokeStyle = color;
        ctx.lineWidth = selected ? 3 : 2;
        ctx.stroke();
      }

      // The extent rectangle: the shape itself when nothing else is known, and a highlight
      // around the selected object.
      if (o.extent && (selected || (!o.box && o.ellipses.length === 0))) {
        const [x0, y0] = [toScreenX(o.extent.min[0]), toScreenY(o.extent.max[1])];
        const [x1, y1] = [toScreenX(o.extent.max[0]), toScreenY(o.extent.min[1])];
        ctx.setLineDash([4, 3]);
        ctx.lineWidth = selected ? 1.5 : 1.25;
        ctx.strokeStyle = selected ? '#ffffff' : color;
        const pad = selected ? 4 : 0;
        ctx.strokeRect(x0 - pad, y0 - pad, x1 - x0 + 2 * pad, y1 - y0 + 2 * pad);
        ctx.setLineDash([]);
      }
    }

    // Labels in a second pass, so that no later shape covers them.
    for (const o of objects) {
      const at = objectLabelAnchor(o);
      if (!at) continue;
      const conf = o.confidence !== null ? ` ${o.confidence.toFixed(2)}` : '';
      label(`${o.id} · ${o.cls ?? 'unknown'}${conf}`, at[0] + 5, at[1] - 3, classColor(o.cls), 'left', 'bottom',
        o.id === S.selectedId ? LABEL_FONT_BOLD : LABEL_FONT);
    }
  }

  // Screen point at the top-right corner of an object, where its label goes: of its box if it
  // has one, else of its ellipses, else of its extent.
  function objectLabelAnchor(o) {
    let pts;
    if (o.box) pts = boxCorners(o.box);
    else if (o.ellipses.length) pts = objectOutline({ extent: null, box: null, ellipses: o.ellipses });
    else pts = objectOutline(o);
    if (pts.length === 0) return null;
    let maxX = -Infinity;
    let maxY = -Infinity;
    for (const [x, y] of pts) { maxX = Math.max(maxX, x); maxY = Math.max(maxY, y); }
    return [toScreenX(maxX), toScreenY(maxY)];
  }

  function drawTracks(tracks) {
    for (const t of tracks) {
      const color = t.label !== null && Object.hasOwn(CLASS_COLORS, t.label) ? CLASS_COLORS[t.label] : '#ffffff';
      const sx = toScreenX(t.x);
      const sy = toScreenY(t.y);
      ctx.globalAlpha = t.state === null || t.state === 'confirmed' ? 1 : 0.55;

      // Trail: where the track has been.
      if (t.trail.length > 1) {
        ctx.beginPath();
        t.trail.forEach(([x, y], i) => {
          if (i === 0) ctx.moveTo(toScreenX(x), toScreenY(y));
          else ctx.lineTo(toScreenX(x), toScreenY(y));
        });
        ctx.strokeStyle = color;
        ctx.lineWidth = 1.5;
        ctx.globalAlpha *= 0.6;
        ctx.stroke();
        ctx.globalAlpha /= 0.6;
      }

      // Position uncertainty (1 sigma), when it is big enough to see.
      if (t.sigma !== null && t.sigma * S.view.scale > 6) {
        ctx.beginPath();
        ctx.arc(sx, sy, t.sigma * S.view.scale, 0, 2 * Math.PI);
        ctx.setLineDash([3, 3]);
        ctx.strokeStyle = 'rgba(255, 255, 255, 0.35)';
        ctx.lineWidth = 1;
        ctx.stroke();
        ctx.setLineDash([]);
      }

      // Velocity: an arrow to where the track will be in one second.
      const ex = toScreenX(t.x + t.vx);
      const ey = toScreenY(t.y + t.vy);
      if (Math.hypot(ex - sx, ey - sy) > 3) arrow(sx, sy, ex, ey, '#ffffff');

      // Heading tick, when the tracker knows the heading.
      if (t.heading !== null) {
        const h = rad(t.heading);
        ctx.beginPath();
        ctx.moveTo(sx, sy);
        ctx.lineTo(sx + 14 * Math.cos(h), sy - 14 * Math.sin(h));
        ctx.strokeStyle = color;
        ctx.lineWidth = 3;
        ctx.stroke();
      }

      // The dot; a ring around it when a camera confirmed the track.
      ctx.beginPath();
      ctx.arc(sx, sy, 4.5, 0, 2 * Math.PI);
      ctx.fillStyle = color;
      ctx.fill();
      ctx.strokeStyle = '#0b0e13';
      ctx.lineWidth = 1.5;
      ctx.stroke();
      if (t.camera) {
        ctx.beginPath();
        ctx.arc(sx, sy, 7.5, 0, 2 * Math.PI);
        ctx.strokeStyle = CAMERA_COLOR;
        ctx.lineWidth = 1;
        ctx.stroke();
      }

      label(`${t.id} ${t.label ?? ''}`.trim(), sx + 9, sy + 9, '#ffffff', 'left', 'top', LABEL_FONT_BOLD);
      ctx.globalAlpha = 1;
    }
  }

  function arrow(x0, y0, x1, y1, color) {
    const a = Math.atan2(y1 - y0, x1 - x0);
    const head = Math.min(7, Math.hypot(x1 - x0, y1 - y0) / 2);
    ctx.strokeStyle = color;
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    ctx.moveTo(x0, y0);
    ctx.lineTo(x1, y1);
    ctx.moveTo(x1 - head * Math.cos(a - 0.45), y1 - head * Math.sin(a - 0.45));
    ctx.lineTo(x1, y1);
    ctx.lineTo(x1 - head * Math.cos(a + 0.45), y1 - head * Math.sin(a + 0.45));
    ctx.stroke();
  }

  // Lidars: a cyan ring with a heading line. Cameras: a white square with a view wedge.
  function drawSensors() {
    for (const s of S.config.sensors) {
      const sx = toScreenX(s.x);
      const sy = toScreenY(s.y);
      const h = s.heading !== null ? rad(s.heading) : null;
      const camera = s.kind === 'camera';
      const color = camera ? CAMERA_COLOR : LIDAR_COLOR;
      ctx.strokeStyle = color;
      ctx.fillStyle = color;

      if (camera) {
        if (h !== null) {
          ctx.beginPath();
          ctx.moveTo(sx + 22 * Math.cos(h - 0.45), sy - 22 * Math.sin(h - 0.45));
          ctx.lineTo(sx, sy);
          ctx.lineTo(sx + 22 * Math.cos(h + 0.45), sy - 22 * Math.sin(h + 0.45));
          ctx.lineWidth = 1.5;
          ctx.stroke();
        }
        ctx.fillRect(sx - 5, sy - 5, 10, 10);
        ctx.strokeStyle = '#0b0e13';
        ctx.lineWidth = 1;
        ctx.strokeRect(sx - 5, sy - 5, 10, 10);
      } else {
        if (h !== null) {
          ctx.beginPath();
          ctx.moveTo(sx + 7 * Math.cos(h), sy - 7 * Math.sin(h));
          ctx.lineTo(sx + 22 * Math.cos(h), sy - 22 * Math.sin(h));
          ctx.lineWidth = 2;
          ctx.stroke();
        }
        ctx.beginPath();
        ctx.arc(sx, sy, 6, 0, 2 * Math.PI);
        ctx.lineWidth = 2;
        ctx.stroke();
        ctx.beginPath();
        ctx.arc(sx, sy, 2, 0, 2 * Math.PI);
        ctx.fill();
      }
      label(s.name, sx + 9, sy + 9, color, 'left', 'top');
    }
  }

  // ---- Panel -------------------------------------------------------------------------------

  function el(tag, attrs = {}, ...children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) {
      if (k === 'class') e.className = v;
      else if (k === 'style') e.style.cssText = v;
      else e.setAttribute(k, v);
    }
    for (const c of children) if (c !== null && c !== undefined) e.append(c);
    return e;
  }

  function setPill(node, text, kind) {
    node.textContent = text;
    node.className = `pill ${kind}`;
  }

  function bannerText() {
    if (S.sse === 'connecting') return 'Connecting to the view server…';
    if (S.sse !== 'open') return 'View server lost — reconnecting';
    if (S.status && !S.status.root.connected) {
      const detail = S.status.root.detail;
      return `Root unreachable — reconnecting${detail ? `: ${detail}` : ''}`;
    }
    return '';
  }

  // The connection part of the panel and the banner. These stay live while paused: the state
  // of the links matters more than a frozen picture.
  function renderConnections() {
    const banner = bannerText();
    dom.banner.textContent = banner;
    dom.banner.hidden = banner === '';
    dom.banner.classList.toggle('info', S.sse === 'connecting');   // first connection: not an alarm

    if (S.sse === 'open') setPill(dom.connSse, 'connected', 'ok');
    else if (S.sse === 'connecting') setPill(dom.connSse, 'connecting…', 'wait');
    else setPill(dom.connSse, 'lost — reconnecting', 'bad');

    const st = S.status;
    const stale = S.sse !== 'open';
    renderLink(dom.connRoot, dom.connRootDetail, st ? st.root : null, stale, 'unreachable');

    const hasTracker = st ? st.tracker !== null : Boolean(S.config && S.config.hasTracker);
    dom.rowTracker.hidden = !hasTracker;
    if (hasTracker) renderLink(dom.connTracker, dom.connTrackerDetail, st ? st.tracker : null, stale, 'disconnected');

    const extra = [];
    if (st && st.skippedEvents > 0) extra.push(`${st.skippedEvents} events skipped by the server`);
    if (S.malformed > 0) extra.push(`${S.malformed} malformed events ignored`);
    dom.connExtra.textContent = extra.join(' · ');

    dom.topology.textContent = S.config && S.config.topology ? `topology ${S.config.topology}` : '';
  }

  function renderLink(pill, detail, link, stale, downWord) {
    if (!link) {
      setPill(pill, 'unknown', '');
      detail.textContent = '';
      return;
    }
    if (stale) setPill(pill, link.connected ? 'connected (stale)' : `${downWord} (stale)`, '');
    else if (link.connected) setPill(pill, 'connected', 'ok');
    else setPill(pill, downWord, 'bad');
    detail.textContent = [link.target, link.detail].filter((s) => s).join(' — ');
  }

  // Latency of the last map, and the rate of maps over the last few seconds. Runs on every
  // event (the status heartbeat included), so the rate falls to zero when maps stop coming.
  const RATE_WINDOW_MS = 3000;
  function renderLatency() {
    const last = S.latencies.length ? S.latencies[S.latencies.length - 1] : null;
    dom.latency.textContent = last === null ? '—' : `${last.toFixed(1)} ms`;
    const now = Date.now();
    while (S.mapArrivals.length > 0 && now - S.mapArrivals[0] > RATE_WINDOW_MS) S.mapArrivals.shift();
    const windowMs = S.firstMapAt === null ? 0 : Math.min(RATE_WINDOW_MS, now - S.firstMapAt);
    if (windowMs < 500) dom.rate.textContent = '—';
    else dom.rate.textContent = `${(S.mapArrivals.length / (windowMs / 1000)).toFixed(1)} Hz`;
  }

  // Everything in the panel that comes from the shown map and tracks.
  function renderMapPanel() {
    const map = S.shown.map;
    const tracks = S.shown.tracks;
    dom.pausedTag.hidden = !S.paused;
    dom.epoch.textContent = map ? String(map.epoch) : '—';
    dom.revision.textContent = '';
    if (map) {
      dom.revision.append(String(map.revision));
      if (map.late) dom.revision.append(el('span', { class: 'tag bad' }, 'late'));
    } else {
      dom.revision.textContent = '—';
    }
    dom.objects.textContent = map ? String(map.objects.length) : '—';
    dom.tracks.textContent = tracks ? String(tracks.tracks.length) : '—';
    renderNodes();
    renderFences();
    renderDetails();
  }

  function renderNodes() {
    const rows = new Map();   // by name, in config order then map order
    if (S.config) for (const n of S.config.nodes) rows.set(n.name, { name: n.name, role: n.role, state: null });
    if (S.shown.map) {
      for (const n of S.shown.map.nodes) {
        const row = rows.get(n.name) || { name: n.name, role: '' };
        row.state = n;
        rows.set(n.name, row);
      }
    }
    const body = [];
    for (const r of rows.values()) {
      let state;
      if (!r.state) state = el('span', { class: 'dim' }, r.role === 'aggregator' ? 'aggregator' : '—');
      else if (r.state.missing) state = el('span', { class: 'state-missing' }, 'MISSING');
      else state = el('span', { class: 'state-ok' }, 'ok');
      const last = r.state && r.state.lastEpoch !== null ? String(r.state.lastEpoch) : '—';
      body.push(el('tr', {}, el('td', {}, r.name), el('td', {}, state), el('td', { class: 'num' }, last)));
    }
    if (body.length === 0) body.push(el('tr', {}, el('td', { class: 'dim', colspan: '3' }, 'No nodes known yet.')));
    dom.nodes.replaceChildren(...body);
  }

  function renderFences() {
    const states = fenceStates();
    const names = new Set();
    if (S.config) for (const g of S.config.geofences) names.add(g.name);
    for (const name of states.keys()) names.add(name);
    const items = [];
    for (const name of names) {
      const st = states.get(name);
      let text;
      let cls = 'dim';
      if (!st) text = 'no data';
      else if (st.occupied) {
        cls = 'fence-occupied';
        text = `occupied by ${st.objects.length ? st.objects.join(', ') : '?'}`;
      } else {
        cls = 'fence-free';
        text = 'free';
      }
      items.push(el('li', {}, `${name}: `, el('span', { class: cls }, text)));
    }
    if (items.length === 0) items.push(el('li', { class: 'dim' }, S.config ? 'None configured.' : '—'));
    dom.fences.replaceChildren(...items);
  }

  function renderLegend() {
    const items = Object.entries(CLASS_COLORS).map(([name, color]) =>
      el('li', {}, el('span', { class: 'swatch', style: `background:${color}` }), name));
    items.push(
      el('li', {}, el('span', { class: 'swatch', style: `background:${LIDAR_COLOR};border-radius:50%` }), 'lidar'),
      el('li', {}, el('span', { class: 'swatch', style: `background:${CAMERA_COLOR}` }), 'camera'),
      el('li', {}, el('span', { class: 'swatch', style: 'background:#fff;border-radius:50%' }), 'track (arrow: 1 s)'),
    );
    dom.legend.replaceChildren(...items);
  }

  const fmt = (v, digits = 2) => (v === null || v === undefined ? '—' : v.toFixed(digits));

  function renderDetails() {
    dom.detailsHint.hidden = S.selectedId !== null;
    if (S.selectedId === null) {
      dom.details.replaceChildren();
      dom.details.classList.remove('gone');
      return;
    }
    const map = S.shown.map;
    const current = map ? map.objects.find((o) => o.id === S.selectedId) : undefined;
    if (current) {
      S.selectedLast = current;
      S.selectedLastEpoch = map.epoch;
    }
    const o = current || S.selectedLast;
    const parts = [];
    if (!current) {
      parts.push(el('div', { class: 'gone-note' },
        `Object ${S.selectedId} is gone: not in the map of epoch ${map ? map.epoch : '—'}` +
        (S.selectedLastEpoch !== null ? ` (last seen in epoch ${S.selectedLastEpoch}).` : '.')));
    }
    if (o) {
      const color = classColor(o.cls);
      parts.push(el('h3', {}, el('span', { class: 'swatch', style: `background:${color}` }), `Object ${o.id}`));
      const rows = [
        ['Points', String(o.points)],
        ['Sensors', o.sensors.length ? o.sensors.join(', ') : '—'],
        ['Class', `${o.cls ?? 'unknown'}${o.confidence !== null ? ` (confidence ${fmt(o.confidence)})` : ''}`],
      ];
      if (o.box) {
        const b = o.box;
        rows.push(['Box', `${fmt(b.length)} × ${fmt(b.width)} m, yaw ${fmt(b.yaw, 1)}°`]);
        rows.push(['Box centre', `(${fmt(b.cx)}, ${fmt(b.cy)}) m`]);
        if (b.zmin !== null || b.zmax !== null) rows.push(['Box height', `z ${fmt(b.zmin)} … ${fmt(b.zmax)} m`]);
      } else {
        rows.push(['Box', 'none']);
      }
      if (o.extent) {
        const e = o.extent;
        rows.push(['Extent', `x ${fmt(e.min[0])} … ${fmt(e.max[0])}, y ${fmt(e.min[1])} … ${fmt(e.max[1])}, ` +
          `z ${fmt(e.min[2])} … ${fmt(e.max[2])} m`]);
      }
      parts.push(el('table', { class: 'kv' },
        ...rows.map(([k, v]) => el('tr', {}, el('th', {}, k), el('td', {}, v)))));

      const head = el('tr', {}, ...['Sensor', 'Points', 'a (m)', 'b (m)', 'Angle'].map((h, i) =>
        el('th', i ? { class: 'num' } : {}, h)));
      const ell = o.ellipses.map((e) => el('tr', {},
        el('td', {}, e.sensor ?? '—'),
        el('td', { class: 'num' }, e.points === null ? '—' : String(e.points)),
        el('td', { class: 'num' }, fmt(e.a)),
        el('td', { class: 'num' }, fmt(e.b)),
        el('td', { class: 'num' }, `${fmt(e.angle, 1)}°`)));
      parts.push(el('div', { class: 'sub' }, `Ellipses (${o.ellipses.length})`));
      if (ell.length) parts.push(el('table', { class: 'grid' }, el('thead', {}, head), el('tbody', {}, ...ell)));
    }
    dom.details.classList.toggle('gone', !current);
    dom.details.replaceChildren(...parts);
  }

  // ---- Selection ---------------------------------------------------------------------------

  // Area of the smallest of the object's shapes (ellipses, box, extent) that contains the
  // world point (x, y), or null when none does.
  function containingArea(o, x, y, tol) {
    let best = null;
    const take = (area) => { if (best === null || area < best) best = area; };
    for (const e of o.ellipses) {
      const c = Math.cos(rad(e.angle));
      const s = Math.sin(rad(e.angle));
      const u = (x - e.cx) * c + (y - e.cy) * s;
      const v = -(x - e.cx) * s + (y - e.cy) * c;
      const a = e.a + tol;
      const b = e.b + tol;
      if ((u * u) / (a * a) + (v * v) / (b * b) <= 1) take(Math.PI * e.a * e.b);
    }
    if (o.box) {
      const bx = o.box;
      const c = Math.cos(rad(bx.yaw));
      const s = Math.sin(rad(bx.yaw));
      const u = (x - bx.cx) * c + (y - bx.cy) * s;
      const v = -(x - bx.cx) * s + (y - bx.cy) * c;
      if (Math.abs(u) <= bx.length / 2 + tol && Math.abs(v) <= bx.width / 2 + tol) take(bx.length * bx.width);
    }
    if (o.extent) {
      const [x0, y0] = o.extent.min;
      const [x1, y1] = o.extent.max;
      if (x >= Math.min(x0, x1) - tol && x <= Math.max(x0, x1) + tol &&
          y >= Math.min(y0, y1) - tol && y <= Math.max(y0, y1) + tol) {
        take(Math.abs((x1 - x0) * (y1 - y0)));
      }
    }
    return best;
  }

  // The object under a screen point: the smallest containing shape wins, and among equals the
  // one drawn last (topmost).
  function objectAt(sx, sy) {
    if (!S.shown.map) return null;
    const x = toWorldX(sx);
    const y = toWorldY(sy);
    const tol = HIT_TOLERANCE_PX / S.view.scale;
    let best = null;
    let bestArea = Infinity;
    for (const o of S.shown.map.objects) {
      const area = containingArea(o, x, y, tol);
      if (area !== null && area <= bestArea) {
        best = o;
        bestArea = area;
      }
    }
    return best;
  }

  function select(o) {
    S.selectedId = o ? o.id : null;
    S.selectedLast = o || null;
    S.selectedLastEpoch = o && S.shown.map ? S.shown.map.epoch : null;
    render();
  }

  // ---- User input --------------------------------------------------------------------------

  let drag = null;        // {x, y, cx, cy, moved} while the primary button is down
  let redrawQueued = false;

  // Coalesces redraws of fast pointer and wheel input into one per frame.
  function requestRedraw() {
    if (redrawQueued) return;
    redrawQueued = true;
    requestAnimationFrame(() => {
      redrawQueued = false;
      safely(drawMap);
    });
  }

  function safely(fn) {
    try {
      fn();
    } catch (err) {
      console.error('fogmap view:', err);
    }
  }

  function canvasPoint(ev) {
    const r = canvas.getBoundingClientRect();
    return [ev.clientX - r.left, ev.clientY - r.top];
  }

  function showCursor(ev) {
    const [sx, sy] = canvasPoint(ev);
    dom.cursor.textContent = `x ${toWorldX(sx).toFixed(2)} m   y ${toWorldY(sy).toFixed(2)} m`;
  }

  canvas.addEventListener('pointerdown', (ev) => {
    if (ev.button !== 0) return;
    try {
      canvas.setPointerCapture(ev.pointerId);   // keep receiving moves outside the canvas
    } catch (err) {
      // Synthetic pointers cannot be captured; panning still works inside the canvas.
    }
    drag = { x: ev.clientX, y: ev.clientY, cx: S.view.cx, cy: S.view.cy, moved: false };
  });

  canvas.addEventListener('pointermove', (ev) => {
    showCursor(ev);
    if (!drag) return;
    const dx = ev.clientX - drag.x;
    const dy = ev.clientY - drag.y;
    if (!drag.moved && Math.hypot(dx, dy) < CLICK_SLOP_PX) return;
    drag.moved = true;
    canvas.classList.add('dragging');
    S.viewTouched = true;
    S.view.cx = drag.cx - dx / S.view.scale;
    S.view.cy = drag.cy + dy / S.view.scale;
    requestRedraw();
  });

  const endDrag = (ev, cancelled) => {
    if (!drag) return;
    const wasClick = !drag.moved && !cancelled;
    drag = null;
    canvas.classList.remove('dragging');
    if (wasClick) {
      const [sx, sy] = canvasPoint(ev);
      safely(() => select(objectAt(sx, sy)));
      safely(publishState);
    }
  };
  canvas.addEventListener('pointerup', (ev) => endDrag(ev, false));
  canvas.addEventListener('pointercancel', (ev) => endDrag(ev, true));
  canvas.addEventListener('pointerleave', () => { dom.cursor.textContent = ''; });

  // Zoom about the cursor: the world point under it stays put.
  canvas.addEventListener('wheel', (ev) => {
    ev.preventDefault();
    const perUnit = ev.deltaMode === WheelEvent.DOM_DELTA_LINE ? 0.05 : ev.deltaMode === WheelEvent.DOM_DELTA_PAGE ? 1 : 0.0015;
    const factor = Math.exp(-ev.deltaY * perUnit);
    const [sx, sy] = canvasPoint(ev);
    const wx = toWorldX(sx);
    const wy = toWorldY(sy);
    S.view.scale = clamp(S.view.scale * factor, MIN_SCALE, MAX_SCALE);
    S.view.cx = wx - (sx - S.width / 2) / S.view.scale;
    S.view.cy = wy + (sy - S.height / 2) / S.view.scale;
    S.viewTouched = true;
    showCursor(ev);
    requestRedraw();
  }, { passive: false });

  function togglePause() {
    S.paused = !S.paused;
    dom.pause.textContent = S.paused ? 'Resume' : 'Pause';
    dom.pause.setAttribute('aria-pressed', String(S.paused));
    if (!S.paused) {
      // Resume: show the newest state at once.
      S.shown.map = S.latest.map;
      S.shown.tracks = S.latest.tracks;
    }
    safely(render);
    safely(publishState);
  }

  dom.pause.addEventListener('click', togglePause);
  dom.fit.addEventListener('click', () => {
    safely(() => { fitView(); drawMap(); });
  });

  window.addEventListener('keydown', (ev) => {
    if (ev.target instanceof HTMLElement && ev.target.closest('button, input, textarea, select')) return;
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    if (ev.key === ' ') { ev.preventDefault(); togglePause(); }
    else if (ev.key === 'f' || ev.key === 'F') { safely(() => { fitView(); drawMap(); }); }
    else if (ev.key === 'Escape') { safely(() => select(null)); safely(publishState); }
  });

  // Redraw on any change of the canvas size (window resize, panel layout).
  if (typeof ResizeObserver === 'function') new ResizeObserver(requestRedraw).observe(canvas);
  else window.addEventListener('resize', requestRedraw);

  // ---- Start -------------------------------------------------------------------------------

  renderLegend();
  safely(fitView);
  safely(render);
  afterEvent();
  connect();
})();
