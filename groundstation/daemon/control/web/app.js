// floe live map. Vanilla JS, no dependencies, no build step; served by the daemon.
// Data: WebSocket /ws (hello, full state, event batches; reconnects and catches up with
// ?since=N). Writes: the same HTTP API as the CLI, with the token (Authorization: Bearer).
// Frame: local ENU metres (x east, y north), headings rad counter-clockwise from east.
(function () {
  "use strict";

  const PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"];
  const DRIFT_ARROW_S = 60;      // drift arrows show where a target is in 60 s
  const WIND_PX_PER_M_S = 4;     // the wind arrow: 4 px per m/s (12..80 px)
  const ELLIPSE_K = 2;           // ellipses at 2 standard deviations
  const MAX_EVENTS = 300;
  const $ = (id) => document.getElementById(id);

  const app = {
    doc: null,                 // last state document
    write: false,              // the token is accepted
    token: null,
    tileUrl: null,
    lastSeq: 0,
    instance: null,            // the daemon run the event numbers belong to
    events: [],
    states: 0,                 // state documents received
    frames: 0,                 // map redraws
    view: { cx: 0, cy: 0, scale: 0.25, auto: true },   // scale: pixels per metre
    mode: "select",            // select | add | move
    selected: null,            // target id
    ws: null,
    wsOpen: false,
    reconnects: 0,
    connections: 0,            // WebSocket connections opened (1 + reconnections)
    dirty: true,
    hover: false,              // pointer over the map
    layers: { search: 0, confirmed: 0, tentative: 0, prior: 0 },  // drawn in the last frame
    tileInfo: null,            // the daemon's tile file's metadata (/api/session)
    orient: "north",           // north | ship (ship-up: the ship's course points up)
    rotation: 0,               // rad the map is turned by (ship-up), 0 north-up
    shipCourse: null,          // rad, compass, from the ship's predicted track or its moves
    loiters: [],               // the commanded loiter circles drawn in the last frame
    fence: null,               // the geofence drawn in the last frame (canvas px), or null
  };
  const L = window.floeLayers;

  // ------------------------------------------------------------------ helpers
  const esc = (s) => String(s).replace(/[&<>"']/g, (c) => ({
    "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
  const num = (v) => typeof v === "number" && isFinite(v);
  const fmt = (v, d = 0) => (num(v) ? v.toFixed(d) : "–");
  const colourOf = (index) => PALETTE[index % PALETTE.length];

  function notice(text, isError) {
    const el = $("notice");
    el.textContent = text;
    el.className = "show" + (isError ? " error" : "");
    clearTimeout(notice.timer);
    notice.timer = setTimeout(() => { el.className = isError ? "error" : ""; }, 5000);
  }

  // ------------------------------------------------------------------ token & writes
  function readToken() {
    const params = new URLSearchParams(location.search);
    let token = params.get("token");
    if (token) {
      sessionStorage.setItem("floe-token", token);
      params.delete("token");            // keep it out of the address bar and history
      const rest = params.toString();
      history.replaceState(null, "", location.pathname + (rest ? "?" + rest : "") + location.hash);
    } else {
      token = sessionStorage.getItem("floe-token");
    }
    if (params.get("tiles")) app.tileUrl = params.get("tiles");
    return token;
  }

  async function checkSession() {
    const headers = app.token ? { Authorization: "Bearer " + app.token } : {};
    try {
      const resp = await fetch("/api/session", { headers, cache: "no-store" });
      const body = await resp.json();
      app.write = !!body.write;
      if (body.tile_url && !app.tileUrl) app.tileUrl = body.tile_url;
      if (body.tiles) app.tileInfo = body.tiles;
    } catch (e) {
      app.write = false;
    }
    if (app.token && !app.write) notice("token rejected: read-only", true);
    showAccess();
  }

  function showAccess() {
    document.body.classList.toggle("can-write", app.write);
    const el = $("access");
    el.textContent = app.write ? "control" : "read-only";
    el.className = "badge" + (app.write ? " write" : "");
    if (!app.write) setMode("select");
  }

  async function api(method, path, body) {
    if (!app.write) { notice("read-only: enter the token to control", true); return null; }
    const headers = { Authorization: "Bearer " + app.token };
    if (body !== undefined) headers["Content-Type"] = "application/json";
    let resp, reply;
    try {
      resp = await fetch(path, { method, headers, cache: "no-store",
                                 body: body === undefined ? undefined : JSON.stringify(body) });
      reply = await resp.json();
    } catch (e) {
      notice("daemon unreachable: " + e, true);
      return null;
    }
    if (!resp.ok || !reply.ok) {
      if (resp.status === 401) { app.write = false; showAccess(); }
      notice("refused: " + (reply.error || resp.status), true);
      return null;
    }
    return reply;
  }

  // ------------------------------------------------------------------ websocket
  function connect() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const url = proto + "//" + location.host + "/ws" + (app.lastSeq && app.instance
      ? "?since=" + app.lastSeq + "&instance=" + encodeURIComponent(app.instance) : "");
    const ws = new WebSocket(url);
    app.ws = ws;
    ws.onopen = () => { app.wsOpen = true; app.connections += 1; showConn(); };
    ws.onmessage = (msg) => {
      let data;
      try { data = JSON.parse(msg.data); } catch (e) { return; }
      if (data.type === "hello") {
        if (data.tile_url && !app.tileUrl) app.tileUrl = data.tile_url;
        if (app.instance !== null && data.instance !== app.instance) {
          app.lastSeq = 0;             // the daemon restarted: its events start afresh
          app.events = [];
          $("events").textContent = "";
        }
        app.instance = data.instance || null;
      } else if (data.type === "state") {
        onState(data.state);
      } else if (data.type === "events") {
        onEvents(data.events || [], data.dropped || 0);
      }
    };
    ws.onclose = () => {
      app.wsOpen = false;
      showConn();
      const delay = Math.min(5000, 300 * Math.pow(2, Math.min(app.reconnects, 4)));
      app.reconnects += 1;
      setTimeout(connect, delay);
    };
    ws.onerror = () => { try { ws.close(); } catch (e) { /* closing anyway */ } };
  }

  function showConn() {
    const el = $("conn");
    el.textContent = app.wsOpen ? "live" : "reconnecting…";
    el.className = "badge " + (app.wsOpen ? "ok" : "off");
    if (app.wsOpen) app.reconnects = 0;
  }

  function onState(doc) {
    if (!doc || typeof doc !== "object") return;
    app.doc = doc;
    app.states += 1;
    if (doc.tile_url && !app.tileUrl) app.tileUrl = doc.tile_url;
    $("clock").textContent = "t = " + fmt(doc.t, 1) + " s";
    $("speedup").textContent = num(doc.speedup) && doc.speedup !== 1 ? doc.speedup + "×" : "";
    $("advisory").hidden = !doc.advisory;
    $("wind").textContent = windLabel(doc.wind);
    const plan = doc.plan;
    $("plan-info").textContent = plan && num(plan.t)
      ? "last plan t=" + fmt(plan.t, 1) + " s, " + (plan.status || "") + ", " +
        fmt(plan.solve_time_s * 1000, 0) + " ms" : "";
    // Never move the map under the operator's pointer or while placing a target.
    if (app.view.auto && !app.hover && app.mode === "select") fitView(false);
    updateVehicles(doc);
    updateShipCourse(doc);
    if (G) {
      G.updatePanel($("vehicle-panel").tBodies[0], doc.vehicles || [], colourOf, (v) =>
        (geoFrame && num(v.x_m) && num(v.y_m) ? geoFrame.toLatLng(v.x_m, v.y_m) : null));
    }
    updateTargets(doc);
    $("track-counts").textContent = L.countsText(doc);
    app.dirty = true;
  }

  // "12 m/s from 270° (vehicles 1,2,3)": the wind the daemon's core plans with.
  function windLabel(wind) {
    if (!wind || !num(wind.speed_m_s)) return "wind –";
    const text = wind.speed_m_s < 0.05 ? "calm"
      : fmt(wind.speed_m_s, 0) + " m/s from " + fmt(wind.from_deg, 0) + "°";
    const source = wind.source === "vehicles" && Array.isArray(wind.vehicles)
      ? "vehicles " + wind.vehicles.join(",") : (wind.source || "?");
    return "wind " + text + " (" + source + ")" + (wind.planning === false ? ", not planned with" : "");
  }

  function summary(line) {
    const skip = new Set(["t", "event", "unix_s", "vehicle", "target"]);
    const parts = [];
    if (line.vehicle !== undefined && line.vehicle !== null) parts.push("vehicle=" + line.vehicle);
    if (line.target !== undefined && line.target !== null) parts.push("target=" + line.target);
    if (line.event === "plan" && line.routes && typeof line.routes === "object") {
      parts.push(Object.entries(line.routes).map(([v, r]) =>  // as log_lines.format_routes
        v + " -> " + (Array.isArray(r) && r.length ? r.join(", ") : "-")).join(" | "));
      skip.add("routes"); skip.add("problem"); skip.add("result"); skip.add("hint");
    }
    for (const [k, v] of Object.entries(line)) {
      if (skip.has(k) || v === null || typeof v === "object") continue;
      parts.push(k + "=" + (typeof v === "number" ? +v.toFixed(3) : v));
    }
    return parts.join(" ");
  }

  function onEvents(entries, dropped) {
    const list = $("events");
    const frag = document.createDocumentFragment();
    for (const entry of entries) {
      if (!entry || typeof entry.seq !== "number" || entry.seq <= app.lastSeq) continue;
      app.lastSeq = entry.seq;
      const line = entry.line || {};
      app.events.push(entry);
      const li = document.createElement("li");
      li.dataset.seq = entry.seq;
      if (entry.warning) li.className = "ev-warn";  // the server's log_lines.line_level
      const text = summary(line);
      li.innerHTML = fmt(line.t, 1).padStart(7, " ") + " <b>" + esc(line.event || "?") + "</b> " + esc(text);
      li.title = JSON.stringify(line).slice(0, 2000);
      frag.insertBefore(li, frag.firstChild);
    }
    if (dropped > 0) {
      const li = document.createElement("li");
      li.className = "ev-warn";
      li.textContent = "… " + dropped + " events not shown (too fast or missed)";
      frag.insertBefore(li, frag.firstChild);
    }
    list.insertBefore(frag, list.firstChild);
    while (list.children.length > MAX_EVENTS) list.removeChild(list.lastChild);
    if (app.events.length > MAX_EVENTS) app.events.splice(0, app.events.length - MAX_EVENTS);
  }

  // ------------------------------------------------------------------ tables (keyed rows)
  function keyedRows(tbody, items, build, update) {
    const seen = new Set();
    items.forEach((item, index) => {
      const key = String(item.id);
      seen.add(key);
      let row = tbody.querySelector('tr[data-id="' + CSS.escape(key) + '"]');
      if (!row) {
        row = build(item, index);
        row.dataset.id = key;
      }
      update(row, item, index);
      if (tbody.children[index] !== row) tbody.insertBefore(row, tbody.children[index] || null);
    });
    for (const row of Array.from(tbody.children)) {
      if (!seen.has(row.dataset.id)) row.remove();
    }
  }

  function setCell(cell, text, cls) {
    if (cell.textContent !== text) cell.textContent = text;
    if (cls !== undefined && cell.className !== cls) cell.className = cls;
  }

  function updateVehicles(doc) {
    const vehicles = Array.isArray(doc.vehicles) ? doc.vehicles : [];
    keyedRows($("vehicles").tBodies[0], vehicles, () => {
      const row = document.createElement("tr");
      row.innerHTML = "<td><span class=swatch></span><span class=name></span></td>" +
        "<td></td><td></td><td></td><td></td><td></td><td class=route></td>" +
        "<td class='write-only actions'><button data-act=launch title='arm, take off, hand over to floe'>launch</button>" +
        "<button data-act=release title='stop commanding it'>release</button>" +
        "<button data-act=resume title='give it back to floe'>resume</button>" +
        "<button data-act=rtl title='send it home (RTL); resume gives it back'>rtl</button></td>";
      return row;
    }, (row, v, index) => {
      const c = row.cells;
      row.querySelector(".swatch").style.background = colourOf(index);
      setCell(row.querySelector(".name"), (v.name || v.id) +
        (v.system_id !== undefined && v.system_id !== null ? " #" + v.system_id : ""));
      setCell(c[1], (v.mode || "–") + (v.armed === false ? " (disarmed)" : ""));
      c[1].title = (num(v.alt_m) ? "alt " + fmt(v.alt_m) + " m, " : "") +
        (num(v.speed_m_s) ? fmt(v.speed_m_s, 1) + " m/s" : "");
      setCell(c[2], v.status || "–", "st-" + (v.status || ""));
      setCell(c[3], v.lagging && num(v.telemetry_age_s)
        ? "lagging " + fmt(v.telemetry_age_s, 1) + " s" : v.link || "–",
        v.lagging ? "st-lost" : "st-" + (v.link === "ok" ? "active" : v.link || ""));
      c[3].title = num(v.telemetry_age_s)
        ? "newest position " + fmt(v.telemetry_age_s, 1) + " s old" +
          (v.lagging ? ": planned from a prediction" : "") : "";
      const energy = doc.watch && doc.watch.energy ? doc.watch.energy[v.id] : null;
      setCell(c[4], (num(v.battery_pct) ? fmt(v.battery_pct) + "%" : "–") +
        (energy && num(energy.endurance_left_s)
          ? " · " + fmt(Math.max(0, energy.endurance_left_s) / 60) + " min" +
            (energy.reachable === false ? " · CAN'T REACH SHIP" : "") : ""),
        energy && energy.reachable === false ? "st-lost" : "");
      c[4].title = energy ? "drain " + fmt(energy.rate_pct_min, 2) + " %/min (" +
        energy.source + ")" + (num(energy.turn_home_t)
          ? ", must turn home by t=" + fmt(energy.turn_home_t) + " s" : "") : "";
      setCell(c[5], v.target === null || v.target === undefined ? "–" : String(v.target));
      const route = Array.isArray(v.route) ? v.route.join(" → ") : "";
      setCell(c[6], route || "–");
      c[6].title = route;
      const launch = row.querySelector("button[data-act=launch]");
      const wanted = wantedText(v);
      launch.classList.toggle("wanted", wanted !== null);
      launch.title = wanted === null ? "arm, take off, hand over to floe"
        : "floe asks: launch it (" + wanted + ")";
    });
    updateLaunchWanted(vehicles);
  }

  // the core asks for a spare's launch (a ship watch's relief): one button each over the map
  function wantedText(v) {
    const w = v.launch_wanted;
    if (!w || typeof w !== "object") return null;
    return w.relieves !== null && w.relieves !== undefined
      ? "relief of " + w.relieves : String(w.reason || "launch");
  }

  function updateLaunchWanted(vehicles) {
    const box = $("launch-wanted");
    const wanted = vehicles.filter((v) => wantedText(v) !== null);
    const keys = wanted.map((v) => String(v.id) + ":" + wantedText(v)).join("|");
    if (box.dataset.keys === keys) return;
    box.dataset.keys = keys;
    box.replaceChildren(...wanted.map((v) => {
      const button = document.createElement("button");
      button.type = "button";
      button.dataset.vehicle = String(v.id);
      button.textContent = "launch " + (v.name || v.id) + " (" + wantedText(v) + ")";
      button.title = "catapult it, or let floe launch it: POST /api/vehicles/" + v.id + "/launch";
      return button;
    }));
  }

  function updateTargets(doc) {
    const targets = Array.isArray(doc.targets) ? doc.targets : [];
    const index = L.trackIndex(doc);
    if (app.selected !== null && !targets.some((t) => String(t.id) === app.selected)) {
      select(null);
    }
    keyedRows($("targets").tBodies[0], targets, () => {
      const row = document.createElement("tr");
      row.innerHTML = "<td></td><td></td><td></td><td></td><td></td><td></td><td></td>";
      return row;
    }, (row, t) => {
      const c = row.cells;
      const status = L.statusOf(index, t.id);
      setCell(c[6], status === "confirmed" && !index.has(String(t.id)) ? "" : status);
      row.classList.toggle("tentative", status === "tentative");
      row.classList.toggle("prior", status === "prior");
      setCell(c[0], String(t.id));
      setCell(c[1], fmt(t.sigma, 1));
      setCell(c[2], num(t.sigma) ? fmt(Math.sqrt(Math.max(0, t.sigma)), 1) : "–");
      setCell(c[3], num(t.last_seen_s) && num(doc.t)
        ? fmt(doc.t - t.last_seen_s, 0) + " s ago" : "never");
      setCell(c[4], num(t.vx_m_s) && num(t.vy_m_s) ? fmt(Math.hypot(t.vx_m_s, t.vy_m_s), 2) : "–");
      setCell(c[5], t.lost ? "LOST" : "");
      row.classList.toggle("lost", !!t.lost);
      row.classList.toggle("selected", String(t.id) === app.selected);
    });
    if (app.selected !== null) showSelected();
  }

  function select(id) {
    app.selected = id === null ? null : String(id);
    for (const row of $("targets").tBodies[0].rows) {
      row.classList.toggle("selected", row.dataset.id === app.selected);
    }
    $("selected").hidden = app.selected === null;
    if (app.selected === null && app.mode === "move") setMode("select");
    showSelected();
    app.dirty = true;
  }

  function showSelected() {
    const t = targetById(app.selected);
    if (!t) return;
    $("selected-text").textContent = "target " + t.id + " at (" + fmt(t.x_m) + ", " +
      fmt(t.y_m) + ") m, σ " + fmt(t.sigma, 1) + " m², drift (" + fmt(t.vx_m_s, 2) + ", " +
      fmt(t.vy_m_s, 2) + ") m/s";
  }

  function targetById(id) {
    if (id === null || !app.doc || !Array.isArray(app.doc.targets)) return null;
    return app.doc.targets.find((t) => String(t.id) === String(id)) || null;
  }

  function setMode(mode) {
    app.mode = mode;
    $("map").classList.toggle("adding", mode !== "select");
    $("hint").textContent = mode === "add" ? "click on the map to place the new target (Esc cancels)"
      : mode === "move" ? "click where target " + app.selected + " is now (Esc cancels)" : "";
  }

  // ------------------------------------------------------------------ map geometry
  const canvas = $("map");
  const ctx = canvas.getContext("2d");
  const G = window.floeGeo;
  // Leaflet under the canvas (geo.js); without Leaflet (not installed) or before the
  // mission origin is known, the canvas' own flat projection.
  const basemap = G ? new G.Basemap($("geo"), $("scale-box")) : { ok: false };
  let geoFrame = null;       // the ENU frame of doc.origin (geo.js)

  // the canvas' own size, untouched by the ship-up rotation of its box
  function size() {
    return { w: Math.max(1, canvas.clientWidth), h: Math.max(1, canvas.clientHeight) };
  }

  const geoActive = () => basemap.ok && geoFrame !== null;
  let synced = "";           // the view the map was last set to

  // The map follows app.view before any projection through it (a zoom button, a drag,
  // a fit change the view between frames).
  function ensureSynced() {
    const key = app.view.cx + "," + app.view.cy + "," + app.view.scale;
    if (key !== synced) syncMap();
  }

  function toScreen(x, y) {
    if (geoActive()) {
      ensureSynced();
      const [lat, lon] = geoFrame.toLatLng(x, y);
      return basemap.project(lat, lon);
    }
    const { w, h } = size();
    const v = app.view;
    return [w / 2 + (x - v.cx) * v.scale, h / 2 - (y - v.cy) * v.scale];
  }

  function toWorld(px, py) {
    if (geoActive()) {
      ensureSynced();
      const [lat, lon] = basemap.unproject(px, py);
      return geoFrame.toEnu(lat, lon);
    }
    const { w, h } = size();
    const v = app.view;
    return [v.cx + (px - w / 2) / v.scale, v.cy - (py - h / 2) / v.scale];
  }

  // Latitude/longitude of a canvas point (null without an origin).
  function toLatLon(px, py) {
    if (!geoFrame) return null;
    const [x, y] = toWorld(px, py);
    return geoFrame.toLatLng(x, y);
  }

  // The map under the canvas follows app.view; ship-up turns the canvas and the map
  // together (their box is the view's diagonal, so no corner shows empty).
  function syncMap() {
    const doc = app.doc;
    const origin = doc && doc.origin;
    if (G && origin && num(origin.lat_deg) && num(origin.lon_deg) &&
        (!geoFrame || geoFrame.lat0 !== origin.lat_deg || geoFrame.lon0 !== origin.lon_deg)) {
      geoFrame = G.frame(origin.lat_deg, origin.lon_deg);
    }
    const wrap = $("map-wrap"), stack = $("stack");
    const ww = wrap.clientWidth, wh = wrap.clientHeight;
    let rot = 0;
    if (app.orient === "ship" && num(app.shipCourse)) {
      rot = app.shipCourse;
      const b = doc && doc.boat;
      if (b && num(b.x_m) && num(b.y_m)) { app.view.cx = b.x_m; app.view.cy = b.y_m; }
    }
    const side = rot ? Math.ceil(Math.hypot(ww, wh)) : null;
    const box = side ? [side, side] : [ww, wh];
    const left = side ? (ww - side) / 2 : 0, top = side ? (wh - side) / 2 : 0;
    stack.style.width = box[0] + "px"; stack.style.height = box[1] + "px";
    stack.style.left = left + "px"; stack.style.top = top + "px";
    stack.style.transform = rot ? "rotate(" + (-rot) + "rad)" : "";
    app.rotation = rot;
    if (geoActive()) {
      // the daemon's own tiles once /api/session has said their deepest zoom
      if (app.tileUrl && (app.tileInfo || !app.tileUrl.startsWith("/tiles/"))) {
        basemap.setTiles(app.tileUrl, app.tileInfo);
      }
      const [lat, lon] = geoFrame.toLatLng(app.view.cx, app.view.cy);
      basemap.sync(lat, lon, app.view.scale);
    }
    synced = app.view.cx + "," + app.view.cy + "," + app.view.scale;
  }

  // The ship's course (compass rad): its predicted track's first leg, else its last move.
  const boatSeen = [];
  function updateShipCourse(doc) {
    const ship = doc.watch && doc.watch.ship;
    if (ship && Array.isArray(ship.track) && ship.track.length >= 2) {
      const [a, b] = ship.track;
      if (Math.hypot(b[0] - a[0], b[1] - a[1]) > 1) {
        app.shipCourse = Math.atan2(b[0] - a[0], b[1] - a[1]);
        return;
      }
    }
    const boat = doc.boat;
    if (!boat || !num(boat.x_m) || !num(boat.y_m)) return;
    const last = boatSeen[boatSeen.length - 1];
    if (!last || Math.hypot(boat.x_m - last[0], boat.y_m - last[1]) > 5) {
      boatSeen.push([boat.x_m, boat.y_m]);
      if (boatSeen.length > 2) boatSeen.shift();
    }
    if (boatSeen.length === 2) {
      const [a, b] = boatSeen;
      app.shipCourse = Math.atan2(b[0] - a[0], b[1] - a[1]);
    }
  }

  function contentPoints(doc) {
    const pts = [];
    const add = (x, y) => { if (num(x) && num(y)) pts.push([x, y]); };
    for (const v of doc.vehicles || []) {
      add(v.x_m, v.y_m);
      if (Array.isArray(v.aim)) add(v.aim[0], v.aim[1]);
    }
    for (const t of doc.targets || []) add(t.x_m, t.y_m);
    for (const t of doc.tracks || []) add(t.x_m, t.y_m);
    for (const c of doc.search_cells || []) {
      if (!num(c.size_m)) continue;
      add(c.x_m - c.size_m / 2, c.y_m - c.size_m / 2);
      add(c.x_m + c.size_m / 2, c.y_m + c.size_m / 2);
    }
    if (doc.boat) add(doc.boat.x_m, doc.boat.y_m);
    return pts;
  }

  // Refit only when something leaves the view or everything became small in it.
  function fitView(force) {
    if (!app.doc) return;
    const pts = contentPoints(app.doc);
    if (!pts.length) pts.push([0, 0]);
    const { w, h } = size();
    let minX = Infinity, maxX = -Infinity, minY = Infinity, maxY = -Infinity;
    for (const [x, y] of pts) {
      minX = Math.min(minX, x); maxX = Math.max(maxX, x);
      minY = Math.min(minY, y); maxY = Math.max(maxY, y);
    }
    const margin = (num(app.doc.fov_radius_m) ? app.doc.fov_radius_m : 150) + 50;
    minX -= margin; maxX += margin; minY -= margin; maxY += margin;
    const spanX = Math.max(maxX - minX, 400), spanY = Math.max(maxY - minY, 400);
    const scale = Math.min(w / spanX, h / spanY) * 0.92;
    if (!force) {
      const [ax, ay] = toWorld(w * 0.04, h * 0.04);
      const [bx, by] = toWorld(w * 0.96, h * 0.96);
      const inside = minX >= ax && maxX <= bx && minY >= by && maxY <= ay;
      if (inside && scale < app.view.scale * 2.5) return;
    }
    app.view.cx = (minX + maxX) / 2;
    app.view.cy = (minY + maxY) / 2;
    app.view.scale = scale;
  }

  function zoom(factor, px, py) {
    const { w, h } = size();
    if (px === undefined) { px = w / 2; py = h / 2; }
    // keep the point under (px, py) in place: offsets from the centre scale as 1/scale
    const [wx, wy] = toWorld(px, py);
    const old = app.view.scale;
    app.view.scale = Math.min(50, Math.max(0.002, old * factor));
    const k = old / app.view.scale;
    app.view.cx = wx + (app.view.cx - wx) * k;
    app.view.cy = wy + (app.view.cy - wy) * k;
    app.view.auto = false;
    app.dirty = true;
  }

  // ------------------------------------------------------------------ tiles (optional)
  const tiles = new Map();
  const R_EARTH = 6378137;

  function drawTiles(w, h) {
    const doc = app.doc;
    if (!app.tileUrl || !doc || !doc.origin || !num(doc.origin.lat_deg)) return;
    const lat0 = doc.origin.lat_deg, lon0 = doc.origin.lon_deg;
    const cosLat = Math.cos(lat0 * Math.PI / 180);
    const toLatLon = (x, y) => [lat0 + (y / R_EARTH) * 180 / Math.PI,
                                lon0 + (x / (R_EARTH * cosLat)) * 180 / Math.PI];
    const fromLatLon = (lat, lon) => [(lon - lon0) * Math.PI / 180 * R_EARTH * cosLat,
                                      (lat - lat0) * Math.PI / 180 * R_EARTH];
    const z = Math.max(0, Math.min(19, Math.round(Math.log2(
      156543.034 * cosLat * app.view.scale))));
    const n = Math.pow(2, z);
    const tileX = (lon) => Math.floor((lon + 180) / 360 * n);
    const tileY = (lat) => {
      const r = lat * Math.PI / 180;
      return Math.floor((1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2 * n);
    };
    const tileLon = (x) => x / n * 360 - 180;
    const tileLat = (y) => Math.atan(Math.sinh(Math.PI * (1 - 2 * y / n))) * 180 / Math.PI;
    const [wa, wb] = toWorld(0, 0), [wc, wd] = toWorld(w, h);
    const [latTop, lonLeft] = toLatLon(wa, wb), [latBottom, lonRight] = toLatLon(wc, wd);
    const x0 = tileX(lonLeft), x1 = tileX(lonRight), y0 = tileY(latTop), y1 = tileY(latBottom);
    if ((x1 - x0 + 1) * (y1 - y0 + 1) > 64) return;
    for (let tx = x0; tx <= x1; tx++) {
      for (let ty = y0; ty <= y1; ty++) {
        const url = app.tileUrl.replace("{z}", z).replace("{x}", ((tx % n) + n) % n).replace("{y}", ty);
        let img = tiles.get(url);
        if (!img) {
          img = new Image();
          img.onload = () => { app.dirty = true; };
          img.src = url;
          tiles.set(url, img);
          if (tiles.size > 400) tiles.delete(tiles.keys().next().value);
        }
        if (!img.complete || !img.naturalWidth) continue;
        const [ax, ay] = toScreen(...fromLatLon(tileLat(ty), tileLon(tx)));
        const [bx, by] = toScreen(...fromLatLon(tileLat(ty + 1), tileLon(tx + 1)));
        ctx.drawImage(img, ax, ay, bx - ax, by - ay);
      }
    }
  }

  // ------------------------------------------------------------------ drawing
  function niceStep(pixelsPerMetre) {
    const steps = [10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000];
    for (const s of steps) if (s * pixelsPerMetre >= 70) return s;
    return steps[steps.length - 1];
  }

  const dist = (m) => (m >= 1000 ? (m / 1000) + " km" : m + " m");

  function drawGrid(w, h) {
    const step = niceStep(app.view.scale);
    const [x0, y1] = toWorld(0, 0), [x1, y0] = toWorld(w, h);
    ctx.lineWidth = 1;
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillStyle = "#6d7f90";
    for (let x = Math.ceil(x0 / step) * step; x <= x1; x += step) {
      const [sx] = toScreen(x, 0);
      ctx.strokeStyle = x === 0 ? "#8aa0b4" : "#c9d6e0";
      ctx.beginPath(); ctx.moveTo(sx, 0); ctx.lineTo(sx, h); ctx.stroke();
      ctx.fillText(dist(x), sx + 3, h - 4);
    }
    for (let y = Math.ceil(y0 / step) * step; y <= y1; y += step) {
      const [, sy] = toScreen(0, y);
      ctx.strokeStyle = y === 0 ? "#8aa0b4" : "#c9d6e0";
      ctx.beginPath(); ctx.moveTo(0, sy); ctx.lineTo(w, sy); ctx.stroke();
      ctx.fillText(dist(y), 3, sy - 3);
    }
    // scale bar and north
    const bar = step * app.view.scale;
    ctx.strokeStyle = "#1d2630"; ctx.lineWidth = 2;
    ctx.fillStyle = "rgba(255, 255, 255, 0.8)";
    ctx.fillRect(6, h - 58, bar + 14, 24);
    ctx.beginPath(); ctx.moveTo(12, h - 38); ctx.lineTo(12 + bar, h - 38); ctx.stroke();
    ctx.fillStyle = "#1d2630";
    ctx.fillText(dist(step), 14, h - 43);
    ctx.font = "bold 12px system-ui, sans-serif";
    ctx.fillText("N ↑", w - 34, 46);
  }

  function ellipse(t) {
    const cov = Array.isArray(t.cov_xy) && t.cov_xy.length === 3 && t.cov_xy.every(num)
      ? t.cov_xy : [Math.max(0, t.sigma || 0) / 2, 0, Math.max(0, t.sigma || 0) / 2];
    const [a, b, c] = cov;
    const mean = (a + c) / 2, diff = (a - c) / 2;
    const root = Math.sqrt(diff * diff + b * b);
    const l1 = Math.max(0, mean + root), l2 = Math.max(0, mean - root);
    return { r1: ELLIPSE_K * Math.sqrt(l1), r2: ELLIPSE_K * Math.sqrt(l2),
             angle: 0.5 * Math.atan2(2 * b, a - c) };
  }

  function targetColour(t, fov) {
    if (t.lost) return "#c0392b";
    const r = num(t.sigma) ? Math.sqrt(Math.max(0, t.sigma)) / fov : 0;
    return r < 0.33 ? "#2e7d4f" : r < 0.66 ? "#b7791f" : "#d35400";
  }

  function arrow(x0, y0, x1, y1, colour, width) {
    const ang = Math.atan2(y1 - y0, x1 - x0);
    ctx.strokeStyle = colour; ctx.fillStyle = colour; ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
    ctx.beginPath();
    ctx.moveTo(x1, y1);
    ctx.lineTo(x1 - 8 * Math.cos(ang - 0.4), y1 - 8 * Math.sin(ang - 0.4));
    ctx.lineTo(x1 - 8 * Math.cos(ang + 0.4), y1 - 8 * Math.sin(ang + 0.4));
    ctx.closePath(); ctx.fill();
  }

  function drawTargets(doc, fov) {
    const index = L.trackIndex(doc);
    const drawn = new Set();
    for (const t of doc.targets || []) {
      if (!num(t.x_m) || !num(t.y_m)) continue;
      const status = L.statusOf(index, t.id);
      const style = L.STYLE[status];
      drawn.add(String(t.id));
      app.layers[status] += 1;
      const [sx, sy] = toScreen(t.x_m, t.y_m);
      const colour = style.colour || targetColour(t, fov);
      const e = ellipse(t);
      ctx.save();
      ctx.translate(sx, sy);
      ctx.rotate(-e.angle);
      ctx.beginPath();
      ctx.ellipse(0, 0, Math.max(3, e.r1 * app.view.scale), Math.max(3, e.r2 * app.view.scale),
                  0, 0, 2 * Math.PI);
      if (style.fill) { ctx.fillStyle = colour + "22"; ctx.fill(); }
      ctx.strokeStyle = colour; ctx.lineWidth = style.fill ? 1.5 : 1.2;
      ctx.setLineDash(t.lost ? [5, 4] : style.dash);
      ctx.stroke();
      ctx.restore();
      if (num(t.vx_m_s) && num(t.vy_m_s) && Math.hypot(t.vx_m_s, t.vy_m_s) > 1e-3) {
        const [ex, ey] = toScreen(t.x_m + t.vx_m_s * DRIFT_ARROW_S, t.y_m + t.vy_m_s * DRIFT_ARROW_S);
        const len = Math.hypot(ex - sx, ey - sy);
        const k = len < 14 ? 14 / Math.max(len, 1e-6) : 1;
        arrow(sx, sy, sx + (ex - sx) * k, sy + (ey - sy) * k, colour, 1.5);
      }
      L.marker(ctx, style.marker, sx, sy, colour);
      if (String(t.id) === app.selected) {
        ctx.strokeStyle = "#16324a"; ctx.lineWidth = 2;
        ctx.beginPath(); ctx.arc(sx, sy, 10, 0, 2 * Math.PI); ctx.stroke();
      }
      ctx.fillStyle = status === "tentative" ? "#6d7f90" : "#1d2630";
      ctx.font = (status === "tentative" ? "" : "bold ") + "12px system-ui, sans-serif";
      ctx.fillText(String(t.id) + (t.lost ? " (lost)" : status === "prior" ? " (prior)" : ""),
                   sx + 7, sy - 7);
    }
    for (const [id, view] of index) {  // tracks the page has no target entry for
      if (!drawn.has(id) && L.drawBareTrack(ctx, view, toScreen, app.view.scale)) {
        app.layers[view.status] += 1;
      }
    }
  }

  // The commanded loiter of each vehicle (its mission's last item: centre and radius, from
  // the daemon), drawn as a circle of 96 segments in the ENU frame: round at any zoom,
  // whatever the telemetry rate (a 2 Hz track would draw a 7-sided polygon).
  const LOITER_SEGMENTS = 96;
  function drawLoiters(doc) {
    app.loiters = [];
    (doc.vehicles || []).forEach((v, index) => {
      const l = v.loiter;
      if (!l || !num(l.x_m) || !num(l.y_m) || !num(l.radius_m) || l.radius_m <= 0) return;
      ctx.strokeStyle = colourOf(index); ctx.lineWidth = 1.5; ctx.setLineDash([]);
      ctx.beginPath();
      for (let i = 0; i <= LOITER_SEGMENTS; i++) {
        const a = 2 * Math.PI * i / LOITER_SEGMENTS;
        const [px, py] = toScreen(l.x_m + l.radius_m * Math.cos(a),
                                  l.y_m + l.radius_m * Math.sin(a));
        if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
      }
      ctx.stroke();
      const [cx, cy] = toScreen(l.x_m, l.y_m);
      app.loiters.push({ vehicle: v.id, cx, cy, radius_m: l.radius_m,
                         colour: colourOf(index), segments: LOITER_SEGMENTS });
    });
  }

  // The geofence every vehicle is given (doc.fence: centre in ENU m, radius m), drawn like
  // the loiters as a circle of FENCE_SEGMENTS points in the ENU frame projected through the
  // map: round on the map at any zoom, north-up or ship-up. Solid, orange, over the dashed
  // grey operating area; the legend says how many vehicles hold it verified.
  const FENCE_SEGMENTS = 180;
  const FENCE_COLOUR = "#d9480f";
  function drawFence(doc) {
    const f = doc.fence;
    app.fence = null;
    const vehicles = Array.isArray(doc.vehicles) ? doc.vehicles : [];
    const held = vehicles.filter((v) => v.fence_verified === true).length;
    const key = $("legend-fence");
    if (!f || !num(f.x_m) || !num(f.y_m) || !num(f.radius_m) || f.radius_m <= 0) {
      key.hidden = true;
      return;
    }
    const text = "geofence " + fmt(f.radius_m) + " m · verified on " + held + " of " +
      vehicles.length;
    key.hidden = false;
    if ($("legend-fence-text").textContent !== text) $("legend-fence-text").textContent = text;
    const points = [];
    ctx.strokeStyle = FENCE_COLOUR; ctx.lineWidth = 2.5; ctx.setLineDash([]);
    ctx.beginPath();
    for (let i = 0; i <= FENCE_SEGMENTS; i++) {
      const a = 2 * Math.PI * i / FENCE_SEGMENTS;
      const [px, py] = toScreen(f.x_m + f.radius_m * Math.cos(a), f.y_m + f.radius_m * Math.sin(a));
      if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
      if (i < FENCE_SEGMENTS) points.push([px, py]);
    }
    ctx.stroke();
    const [cx, cy] = toScreen(f.x_m, f.y_m);
    const top = toScreen(f.x_m, f.y_m + f.radius_m);
    ctx.fillStyle = FENCE_COLOUR; ctx.font = "bold 11px system-ui, sans-serif";
    ctx.fillText("geofence", top[0] + 4, top[1] - 5);
    app.fence = { cx, cy, radius_m: f.radius_m, colour: FENCE_COLOUR, segments: FENCE_SEGMENTS,
                  points, verified: held, vehicles: vehicles.length };
  }

  function drawVehicles(doc, fov) {
    const targets = new Map((doc.targets || []).map((t) => [String(t.id), t]));
    (doc.vehicles || []).forEach((v, index) => {
      if (!num(v.x_m) || !num(v.y_m)) return;
      const colour = colourOf(index);
      const faded = v.status === "lost" || v.link === "lost" || v.lagging === true;
      // recent track
      if (Array.isArray(v.track) && v.track.length > 1) {
        ctx.strokeStyle = colour + "88"; ctx.lineWidth = 1.5;
        ctx.beginPath();
        v.track.forEach((p, i) => {
          if (!Array.isArray(p) || !num(p[0]) || !num(p[1])) return;
          const [px, py] = toScreen(p[0], p[1]);
          if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
        });
        ctx.stroke();
      }
      const [sx, sy] = toScreen(v.x_m, v.y_m);
      // lagging: where it is predicted to be now (dashed circle of its uncertainty), from
      // the stale fix the icon shows
      const pr = v.prediction;
      if (pr && num(pr.x_m) && num(pr.y_m) && num(pr.sigma_m)) {
        const [px, py] = toScreen(pr.x_m, pr.y_m);
        ctx.strokeStyle = colour; ctx.lineWidth = 1.5; ctx.setLineDash([6, 4]);
        ctx.beginPath(); ctx.moveTo(sx, sy); ctx.lineTo(px, py); ctx.stroke();
        ctx.beginPath(); ctx.arc(px, py, Math.max(3, pr.sigma_m * app.view.scale), 0, 2 * Math.PI);
        ctx.stroke(); ctx.setLineDash([]);
      }
      // planned sequence: aim point, then the route's targets (dotted)
      const path = [[sx, sy]];
      if (Array.isArray(v.aim) && num(v.aim[0]) && num(v.aim[1])) path.push(toScreen(v.aim[0], v.aim[1]));
      for (const id of Array.isArray(v.route) ? v.route : []) {
        const t = targets.get(String(id));
        if (t && num(t.x_m) && num(t.y_m)) path.push(toScreen(t.x_m, t.y_m));
      }
      if (path.length > 1) {
        ctx.strokeStyle = colour; ctx.lineWidth = 1.5; ctx.setLineDash([2, 5]);
        ctx.beginPath();
        path.forEach(([px, py], i) => (i === 0 ? ctx.moveTo(px, py) : ctx.lineTo(px, py)));
        ctx.stroke(); ctx.setLineDash([]);
      }
      // FOV circle
      ctx.beginPath(); ctx.arc(sx, sy, fov * app.view.scale, 0, 2 * Math.PI);
      ctx.fillStyle = colour + "14"; ctx.fill();
      ctx.strokeStyle = colour + "66"; ctx.lineWidth = 1; ctx.stroke();
      // icon pointing along the heading (canvas y is down: rotate by -heading)
      const psi = num(v.heading_rad) ? v.heading_rad : 0;
      ctx.save();
      ctx.translate(sx, sy); ctx.rotate(-psi);
      ctx.beginPath();
      ctx.moveTo(12, 0); ctx.lineTo(-8, 7); ctx.lineTo(-4, 0); ctx.lineTo(-8, -7); ctx.closePath();
      ctx.fillStyle = faded ? "#9aa5ae" : colour; ctx.fill();
      ctx.strokeStyle = "#fff"; ctx.lineWidth = 1.2; ctx.stroke();
      ctx.restore();
      ctx.fillStyle = "#1d2630"; ctx.font = "12px system-ui, sans-serif";
      const label = (v.name || v.id) + (v.status && v.status !== "active" ? " · " + v.status : "") +
        (v.lagging && num(v.telemetry_age_s) ? " · lagging " + fmt(v.telemetry_age_s, 1) + " s" : "");
      ctx.fillText(label, sx + 12, sy + 16);
    });
  }

  // An arrow in the top-right corner along the direction the air moves (ENU towards
  // vector; canvas y is down), its length growing with the speed, and its label.
  function drawWind(doc, w) {
    const wind = doc.wind;
    if (!wind || !num(wind.wx_m_s) || !num(wind.wy_m_s)) return;
    const label = windLabel(wind).replace(/^wind /, "");
    const cut = label.indexOf(" (");
    const lines = cut < 0 ? [label, ""] : [label.slice(0, cut), label.slice(cut + 1)];
    ctx.font = "12px system-ui, sans-serif";
    const boxW = Math.max(110, ...lines.map((t) => ctx.measureText(t).width)) + 12;
    const cx = w - 8 - boxW / 2, cy = 115;
    ctx.fillStyle = "rgba(255, 255, 255, 0.8)";
    ctx.fillRect(w - 8 - boxW, 54, boxW, 124);
    const speed = Math.hypot(wind.wx_m_s, wind.wy_m_s);
    if (speed >= 0.05) {
      const half = Math.min(80, Math.max(12, speed * WIND_PX_PER_M_S)) / 2;
      const ux = wind.wx_m_s / speed, uy = -wind.wy_m_s / speed;
      arrow(cx - ux * half, cy - uy * half, cx + ux * half, cy + uy * half, "#16324a", 2.5);
    }
    ctx.fillStyle = "#1d2630";
    ctx.textAlign = "center";
    ctx.fillText(lines[0], cx, 68);
    ctx.fillText(lines[1], cx, 172);
    ctx.textAlign = "start";
  }

  // the ship's predicted track (the next 10 min) and its uncertainty; the watch's alarms
  function drawShipTrack(doc) {
    const ship = doc.watch && doc.watch.ship;
    if (!ship || !Array.isArray(ship.track) || ship.track.length < 2) return;
    ctx.setLineDash([6, 5]); ctx.strokeStyle = "#7a4e2d"; ctx.lineWidth = 1.5;
    ctx.beginPath();
    ship.track.forEach((p, i) => {
      const [sx, sy] = toScreen(p[0], p[1]);
      if (i === 0) ctx.moveTo(sx, sy); else ctx.lineTo(sx, sy);
    });
    ctx.stroke(); ctx.setLineDash([]);
    if (num(ship.sigma_m)) {
      const [sx, sy] = toScreen(ship.x_m, ship.y_m);
      ctx.strokeStyle = "rgba(122, 78, 45, 0.5)";
      ctx.beginPath(); ctx.arc(sx, sy, Math.max(3, 2 * ship.sigma_m * app.view.scale), 0,
        2 * Math.PI); ctx.stroke();
    }
  }

  function drawWatch(doc, w, h) {
    const watch = doc.watch;
    if (!watch) return;
    const lines = ["on station " + watch.on_station + " of " + watch.planned_on_station +
      ", spares: " + (watch.spares.length ? watch.spares.join(", ") : "none")];
    if (watch.next_relief) {
      lines.push("next return: " + watch.next_relief.vehicle + " at t=" +
        fmt(watch.next_relief.t));
    }
    const alarms = Array.isArray(watch.alarms) ? watch.alarms : [];
    ctx.font = "12px system-ui, sans-serif";
    const all = lines.concat(alarms);
    const boxW = Math.max(...all.map((t) => ctx.measureText(t).width)) + 12;
    const top = h - 12 - 16 * all.length;
    ctx.fillStyle = "rgba(255, 255, 255, 0.85)";
    ctx.fillRect(w - 8 - boxW, top - 4, boxW, 16 * all.length + 8);
    all.forEach((text, i) => {
      ctx.fillStyle = i >= lines.length ? "#b3261e" : "#1d2630";
      ctx.fillText(text, w - 2 - boxW, top + 12 + 16 * i);
    });
  }

  function drawBoat(doc) {
    const b = doc.boat;
    if (!b || !num(b.x_m) || !num(b.y_m)) return;
    const [sx, sy] = toScreen(b.x_m, b.y_m);
    ctx.beginPath();
    ctx.moveTo(sx - 10, sy - 3); ctx.lineTo(sx + 10, sy - 3); ctx.lineTo(sx + 6, sy + 5);
    ctx.lineTo(sx - 6, sy + 5); ctx.closePath();
    ctx.fillStyle = "#7a4e2d"; ctx.fill();
    ctx.fillRect(sx - 1, sy - 13, 2, 10);
    ctx.fillStyle = "#1d2630"; ctx.font = "12px system-ui, sans-serif";
    ctx.fillText("boat", sx + 12, sy + 4);
  }

  function draw() {
    const { w, h } = size();
    const dpr = window.devicePixelRatio || 1;
    if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
      canvas.width = Math.round(w * dpr);
      canvas.height = Math.round(h * dpr);
      if (app.view.auto) fitView(true);
    }
    syncMap();
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    if (geoActive() && basemap.tiles) {
      ctx.clearRect(0, 0, w, h);  // the operator's tiles show through
    } else {  // a plain background (and the metric grid)
      ctx.fillStyle = "#dfe9f0";
      ctx.fillRect(0, 0, w, h);
      drawTiles(w, h);
      drawGrid(w, h);
    }
    const doc = app.doc;
    if (doc) {
      const fov = num(doc.fov_radius_m) ? doc.fov_radius_m : 150;
      if (num(doc.operating_radius_m) && Array.isArray(doc.operating_center_m)) {
        const [cx, cy] = toScreen(doc.operating_center_m[0], doc.operating_center_m[1]);
        ctx.setLineDash([8, 6]); ctx.strokeStyle = "#8aa0b4"; ctx.lineWidth = 1;
        ctx.beginPath(); ctx.arc(cx, cy, doc.operating_radius_m * app.view.scale, 0, 2 * Math.PI);
        ctx.stroke(); ctx.setLineDash([]);
        ctx.fillStyle = "#5d7388"; ctx.font = "11px system-ui, sans-serif";
        ctx.fillText("operating area", cx - 35,
          cy - doc.operating_radius_m * app.view.scale - 5);
      }
      app.layers = { search: 0, confirmed: 0, tentative: 0, prior: 0 };
      app.layers.search = L.drawSearch(ctx, doc, toScreen, app.view.scale);
      drawFence(doc);  // over the search cells' shading
      drawShipTrack(doc);
      drawBoat(doc);
      drawTargets(doc, fov);
      drawLoiters(doc);
      drawVehicles(doc, fov);
      drawWind(doc, w);
      drawWatch(doc, w, h);
    } else {
      ctx.fillStyle = "#46596b"; ctx.font = "14px system-ui, sans-serif";
      ctx.fillText("waiting for the daemon…", w / 2 - 70, h / 2);
    }
    app.frames += 1;
  }

  function loop() {
    if (app.dirty) { app.dirty = false; draw(); }
    requestAnimationFrame(loop);
  }

  // ------------------------------------------------------------------ interaction
  function nearestTarget(px, py) {
    let best = null, bestD = 14;
    for (const t of (app.doc && app.doc.targets) || []) {
      if (!num(t.x_m) || !num(t.y_m)) continue;
      const [sx, sy] = toScreen(t.x_m, t.y_m);
      const d = Math.hypot(sx - px, sy - py);
      if (d < bestD) { best = t; bestD = d; }
    }
    return best;
  }

  async function mapClick(px, py) {
    const [x, y] = toWorld(px, py);
    const pos = { x_m: Math.round(x * 10) / 10, y_m: Math.round(y * 10) / 10 };
    if (app.mode === "add") {
      setMode("select");
      const body = Object.assign({}, pos);
      const id = $("new-id").value.trim();
      if (id) body.id = id;
      const sigma = $("new-sigma").value.trim();
      if (sigma) {
        const s = Number(sigma);
        if (!isFinite(s) || s < 0) { notice("σ0 must be a number >= 0", true); return; }
        body.sigma0 = s;
      }
      const reply = await api("POST", "/api/targets", body);
      if (reply) {
        $("new-id").value = "";
        notice("added target " + reply.target + " at (" + pos.x_m + ", " + pos.y_m + ") m");
        select(reply.target);
      }
    } else if (app.mode === "move" && app.selected !== null) {
      setMode("select");
      const id = app.selected;
      const reply = await api("PUT", "/api/targets/" + encodeURIComponent(id), pos);
      if (reply) {
        notice("target " + id + " re-seated at (" + fmt(reply.x_m, 1) + ", " + fmt(reply.y_m, 1) +
               ") m, sigma " + fmt(reply.sigma, 1) + " m²");
      }
    } else {
      const t = nearestTarget(px, py);
      select(t ? t.id : null);
    }
  }

  // Fleet actions: each asks for a confirmation, then shows each vehicle's answer.
  const FLEET_WORDS = { release: "Release", rtl: "Send home (RTL)", resume: "Resume" };
  function setupFleet() {
    let pending = null;
    const ask = $("fleet-confirm");
    const answer = $("fleet-answer");
    $("fleet").addEventListener("click", (e) => {
      const button = e.target.closest("button[data-fleet]");
      if (!button) return;
      pending = button.dataset.fleet;
      const n = ((app.doc && app.doc.vehicles) || []).length;
      $("fleet-question").textContent = FLEET_WORDS[pending] + " all " + n + " vehicles?";
      ask.hidden = false;
      $("fleet-yes").focus();
    });
    $("fleet-no").onclick = () => { pending = null; ask.hidden = true; };
    $("fleet-yes").onclick = async () => {
      const action = pending;
      pending = null;
      ask.hidden = true;
      if (!action) return;
      const reply = await api("POST", "/api/fleet/" + action);
      if (!reply) return;
      answer.replaceChildren();
      for (const r of reply.results || []) {
        const li = document.createElement("li");
        li.textContent = r.ok ? (r.what || ("vehicle " + r.vehicle + ": done"))
          : "vehicle " + r.vehicle + " refused: " + r.error;
        if (!r.ok) li.className = "error";
        li.dataset.vehicle = r.vehicle;
        answer.appendChild(li);
      }
      notice(action + " all: " + reply.done + " done, " + reply.refused + " refused",
             reply.refused > 0);
    };
  }

  function setupInteraction() {
    let drag = null;
    // Pointer events: mouse, pen and touch (tablets in the field) alike.
    canvas.addEventListener("pointerenter", () => { app.hover = true; });
    canvas.addEventListener("pointerleave", () => { app.hover = false; });
    canvas.addEventListener("pointerdown", (e) => {
      if (e.button !== 0) return;
      drag = { x: e.offsetX, y: e.offsetY, cx: app.view.cx, cy: app.view.cy, moved: false };
      canvas.setPointerCapture(e.pointerId);
    });
    canvas.addEventListener("pointermove", (e) => {
      const [wx, wy] = toWorld(e.offsetX, e.offsetY);
      const ll = toLatLon(e.offsetX, e.offsetY);
      app.cursor = ll ? { lat: ll[0], lon: ll[1], x_m: wx, y_m: wy } : { x_m: wx, y_m: wy };
      $("cursor").textContent = (ll ? G.latLonText(ll[0], ll[1]) + "  " : "") +
        "x " + fmt(wx) + " m, y " + fmt(wy) + " m";
      if (!drag) return;
      const dx = e.offsetX - drag.x, dy = e.offsetY - drag.y;
      if (!drag.moved && Math.hypot(dx, dy) < 5) return;
      drag.moved = true;
      app.view.auto = false;
      app.view.cx = drag.cx - dx / app.view.scale;
      app.view.cy = drag.cy + dy / app.view.scale;
      app.dirty = true;
    });
    canvas.addEventListener("pointerup", (e) => {
      const d = drag;
      drag = null;
      if (d && !d.moved) mapClick(e.offsetX, e.offsetY);
    });
    canvas.addEventListener("pointercancel", () => { drag = null; });
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      zoom(e.deltaY < 0 ? 1.2 : 1 / 1.2, e.offsetX, e.offsetY);
    }, { passive: false });
    $("fit").onclick = () => { app.view.auto = true; fitView(true); app.dirty = true; };
    $("orient").onclick = () => {
      app.orient = app.orient === "north" ? "ship" : "north";
      $("orient").textContent = app.orient === "north" ? "North up" : "Ship up";
      $("orient").title = app.orient === "north" ? "north is up (click: the ship's course up)"
        : "the ship's course is up (click: north up)";
      app.dirty = true;
    };
    $("zoom-in").onclick = () => zoom(1.5);
    $("zoom-out").onclick = () => zoom(1 / 1.5);
    $("add-target").onclick = () => setMode(app.mode === "add" ? "select" : "add");
    $("move-target").onclick = () => { if (app.selected !== null) setMode("move"); };
    $("remove-target").onclick = async () => {
      const id = app.selected;
      if (id === null) return;
      const reply = await api("DELETE", "/api/targets/" + encodeURIComponent(id));
      if (reply) { notice("removed target " + id); select(null); }
    };
    $("targets").tBodies[0].addEventListener("click", (e) => {
      const row = e.target.closest("tr");
      if (row) select(row.dataset.id);
    });
    $("launch-wanted").addEventListener("click", async (e) => {
      const button = e.target.closest("button[data-vehicle]");
      if (!button) return;
      const id = button.dataset.vehicle;
      const reply = await api("POST", "/api/vehicles/" + encodeURIComponent(id) + "/launch");
      if (reply) notice("launch: vehicle " + (reply.vehicle || id) + " ok");
    });
    $("vehicles").tBodies[0].addEventListener("click", async (e) => {
      const button = e.target.closest("button[data-act]");
      if (!button) return;
      const id = button.closest("tr").dataset.id;
      const act = button.dataset.act;
      const reply = await api("POST", "/api/vehicles/" + encodeURIComponent(id) + "/" + act);
      if (reply) notice(reply.what || (act + ": vehicle " + (reply.vehicle || id) + " ok"));
    });
    setupFleet();
    window.addEventListener("keydown", (e) => {
      if (e.target instanceof HTMLInputElement) return;
      if (e.key === "Escape") setMode("select");
      else if (e.key === "f" || e.key === "F") $("fit").click();
      else if (e.key === "+") zoom(1.5);
      else if (e.key === "-") zoom(1 / 1.5);
    });
    $("token-form").addEventListener("submit", (e) => {
      e.preventDefault();
      const value = $("token").value.trim();
      $("token").value = "";
      app.token = value || null;
      if (value) sessionStorage.setItem("floe-token", value);
      else sessionStorage.removeItem("floe-token");
      checkSession().then(() => { if (app.write) notice("control enabled"); });
    });
    $("forget-token").onclick = () => {
      app.token = null;
      sessionStorage.removeItem("floe-token");
      app.write = false;
      showAccess();
    };
    window.addEventListener("resize", () => { app.dirty = true; });
  }

  // ------------------------------------------------------------------ start
  app.token = readToken();
  setupInteraction();
  showAccess();
  checkSession();
  connect();
  requestAnimationFrame(loop);

  // For tests and the curious: read-only view of the page's model and its map transform.
  window.floe = {
    get state() { return app.doc; },
    get write() { return app.write; },
    get states() { return app.states; },
    get frames() { return app.frames; },
    get events() { return app.events.slice(); },
    get connected() { return app.wsOpen; },
    get connections() { return app.connections; },
    get mode() { return app.mode; },
    get layers() { return Object.assign({}, app.layers); },
    windLabel,
    toScreen, toWorld, toLatLon,
    get cursor() { return app.cursor || null; },
    get loiters() { return app.loiters.slice(); },
    get fence() { return app.fence ? JSON.parse(JSON.stringify(app.fence)) : null; },
    get orient() { return app.orient; },
    get rotation() { return app.rotation; },
    get basemap() {
      return { leaflet: basemap.ok, geo: geoActive(), tiles: !!basemap.tiles,
               tileEvents: basemap.tileEvents ? Object.assign({}, basemap.tileEvents) : null };
    },
  };
})();
