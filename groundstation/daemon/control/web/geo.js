// floe live map: geography. Loaded after Leaflet (/vendor/leaflet/leaflet.js, served by the
// daemon from the xstatic-leaflet package: no CDN) and before app.js, which calls these.
//
// * frame(lat0, lon0): the daemon's local ENU frame (x east, y north, metres from the
//   mission origin) to WGS84 and back, exactly as the daemon converts (pymap3d's
//   geodetic2enu/enu2geodetic on the WGS84 ellipsoid, through ECEF): the cursor's
//   latitude/longitude are the ones GLOBAL_POSITION_INT would give for that point.
// * Basemap: a Leaflet map under the page's canvas. The canvas keeps drawing everything
//   (and takes every pointer event); each frame the map is set to the canvas' view (centre
//   and metres per pixel, fractional zoom) and the canvas projects through the map's Web
//   Mercator, so tiles and drawings agree. Tiles from the daemon's /tiles/{z}/{x}/{y} (the
//   operator's MBTiles or PMTiles file) or none (a plain background); Leaflet's scale bar.
// * vehicle panel rows: airspeed, ground speed, heading, altitude, GPS (GPS_RAW_INT's fix,
//   satellites and HDOP: "RTK fixed, 10 sats, HDOP 1.2", a warning below a 3D fix; else
//   SYS_STATUS' GPS health), battery, link.
(function () {
  "use strict";

  const A = 6378137.0;                 // WGS84 semi-major axis (m)
  const F = 1 / 298.257223563;         // WGS84 flattening
  const E2 = F * (2 - F);              // first eccentricity squared
  const RAD = Math.PI / 180;
  const EQUATOR_M = 2 * Math.PI * A;   // Web Mercator: metres per 256 px at zoom 0, equator
  const num = (v) => typeof v === "number" && isFinite(v);

  function toEcef(latDeg, lonDeg, h) {
    const lat = latDeg * RAD, lon = lonDeg * RAD;
    const s = Math.sin(lat), c = Math.cos(lat);
    const n = A / Math.sqrt(1 - E2 * s * s);
    return [(n + h) * c * Math.cos(lon), (n + h) * c * Math.sin(lon), (n * (1 - E2) + h) * s];
  }

  // ECEF -> geodetic (lat, lon degrees): fixed-point iteration on the latitude; 6 rounds
  // reach well below a millimetre at any height a vehicle flies.
  function fromEcef(x, y, z) {
    const lon = Math.atan2(y, x);
    const p = Math.hypot(x, y);
    let lat = Math.atan2(z, p * (1 - E2));
    for (let i = 0; i < 6; i++) {
      const s = Math.sin(lat);
      const n = A / Math.sqrt(1 - E2 * s * s);
      const h = p / Math.cos(lat) - n;
      lat = Math.atan2(z, p * (1 - E2 * n / (n + h)));
    }
    return [lat / RAD, lon / RAD];
  }

  // The local ENU frame at (lat0, lon0, height 0).
  function frame(lat0, lon0) {
    const o = toEcef(lat0, lon0, 0);
    const sf = Math.sin(lat0 * RAD), cf = Math.cos(lat0 * RAD);
    const sl = Math.sin(lon0 * RAD), cl = Math.cos(lon0 * RAD);
    return {
      lat0, lon0,
      toLatLng(e, n) {
        const x = o[0] - sl * e - sf * cl * n;
        const y = o[1] + cl * e - sf * sl * n;
        const z = o[2] + cf * n;
        return fromEcef(x, y, z);
      },
      toEnu(lat, lon) {
        const p = toEcef(lat, lon, 0);
        const dx = p[0] - o[0], dy = p[1] - o[1], dz = p[2] - o[2];
        return [-sl * dx + cl * dy, -sf * cl * dx - sf * sl * dy + cf * dz];
      },
    };
  }

  // Leaflet zoom for `pxPerMetre` at latitude `lat` (Web Mercator: 256 px span the equator
  // at zoom 0, scaled by 1/cos(lat)).
  function zoomFor(pxPerMetre, lat) {
    return Math.log2(pxPerMetre * EQUATOR_M * Math.cos(lat * RAD) / 256);
  }

  class Basemap {
    constructor(el, scaleHome) {
      const Lf = window.L;
      this.ok = !!(Lf && Lf.map);
      this.tiles = null;
      if (!this.ok) return;
      this.map = Lf.map(el, {
        zoomControl: false, attributionControl: false, dragging: false,
        scrollWheelZoom: false, doubleClickZoom: false, boxZoom: false, keyboard: false,
        touchZoom: false, zoomSnap: 0, zoomAnimation: false, fadeAnimation: false,
        markerZoomAnimation: false, inertia: false, minZoom: 0, maxZoom: 24,
      });
      this.map.setView([0, 0], 2);
      const scale = Lf.control.scale({ metric: true, imperial: false, maxWidth: 140,
                                       position: "bottomleft" });
      scale.addTo(this.map);
      // the scale bar lives outside the map's box, so it never turns with ship-up
      if (scaleHome) scaleHome.appendChild(scale.getContainer());
      this.scale = scale;
    }

    setTiles(url, info) {
      if (!this.ok || this.tiles || !url) return;
      const opts = { minZoom: 0, maxZoom: 24, tileSize: 256, keepBuffer: 1 };
      // above the file's deepest zoom, its tiles are scaled up (minNativeZoom is not
      // set: below a minNativeZoom Leaflet asks for ever more tiles and hangs the page)
      if (info && num(info.max_zoom)) opts.maxNativeZoom = info.max_zoom;
      this.tiles = window.L.tileLayer(url, opts).addTo(this.map);
      this.tileEvents = { load: 0, error: 0 };
      this.tiles.on("tileload", () => { this.tileEvents.load += 1; });
      this.tiles.on("tileerror", () => { this.tileEvents.error += 1; });
    }

    // Set the map to centre (lat, lon) at pxPerMetre; the size may have changed.
    sync(lat, lon, pxPerMetre) {
      if (!this.ok) return;
      this.map.invalidateSize({ animate: false, pan: false });
      const z = Math.max(0, Math.min(24, zoomFor(pxPerMetre, lat)));
      this.map.setView([lat, lon], z, { animate: false });
    }

    // Not latLngToContainerPoint: that rounds to whole pixels (a circle of 30 px would be
    // 3 % out of round, the cursor ~0.5 px off).
    project(lat, lon) {
      const m = this.map;
      const layer = m.project([lat, lon], m.getZoom()).subtract(m.getPixelOrigin());
      const p = m.layerPointToContainerPoint(layer);
      return [p.x, p.y];
    }

    unproject(px, py) {
      const ll = this.map.containerPointToLatLng([px, py]);
      return [ll.lat, ll.lng];
    }
  }

  // 78.93°N 11.92°E (5 decimals: ~1 m)
  function latLonText(lat, lon) {
    if (!num(lat) || !num(lon)) return "–";
    return Math.abs(lat).toFixed(5) + "°" + (lat >= 0 ? "N" : "S") + " " +
      Math.abs(lon).toFixed(5) + "°" + (lon >= 0 ? "E" : "W");
  }

  // ------------------------------------------------------------------ vehicle panel
  const fmt = (v, d = 0) => (num(v) ? v.toFixed(d) : "–");
  const PANEL_COLUMNS = 9;

  function linkText(q) {
    if (!q) return "–";
    let text = q.state || "–";
    if (num(q.telemetry_age_s)) text += " · " + fmt(q.telemetry_age_s, 1) + " s";
    if (num(q.rssi)) text += " · " + q.rssi + "/" + (num(q.remrssi) ? q.remrssi : "–");
    return text;
  }

  // The GPS cell: the daemon's gps_text (GPS_RAW_INT's fix, else SYS_STATUS' health).
  function gpsText(v) {
    if (typeof v.gps_text === "string" && v.gps_text) return v.gps_text;
    return v.gps || "–";
  }

  // A warning: a GPS_RAW_INT below a 3D fix (fix_type < 3, or unknown), else an unhealthy
  // or absent SYS_STATUS GPS.
  function gpsWarning(v) {
    if (v.gps_fix && typeof v.gps_fix === "object") return v.gps_fix.ok !== true;
    return !!v.gps && v.gps !== "ok";
  }

  // One row per vehicle: keyed by id, cells updated in place; `position(v)` its
  // [lat, lon] (the name's tooltip) or null.
  function updatePanel(tbody, vehicles, colourOf, position) {
    const seen = new Set();
    vehicles.forEach((v, index) => {
      const id = String(v.id);
      seen.add(id);
      let row = tbody.querySelector("tr[data-id='" + CSS.escape(id) + "']");
      if (!row) {
        row = document.createElement("tr");
        row.dataset.id = id;
        for (let i = 0; i < PANEL_COLUMNS; i++) row.appendChild(document.createElement("td"));
        tbody.appendChild(row);
      }
      const c = row.cells;
      const texts = [
        String(v.name || v.id),
        fmt(v.airspeed_m_s, 1),
        fmt(v.groundspeed_m_s, 1),
        num(v.heading_deg) ? fmt(v.heading_deg) + "°" : "–",
        fmt(v.alt_m),
        gpsText(v),
        fmt(v.battery_v, 1),
        num(v.battery_pct) ? fmt(v.battery_pct) : "–",
        linkText(v.link_quality),
      ];
      texts.forEach((t, i) => { if (c[i].textContent !== t) c[i].textContent = t; });
      c[0].style.borderLeft = "4px solid " + colourOf(index);
      c[5].className = gpsWarning(v) ? "st-lost gps-warn" : "";
      c[5].title = v.gps_fix ? "GPS_RAW_INT" + (v.gps ? "; SYS_STATUS GPS: " + v.gps : "")
        : (v.gps ? "SYS_STATUS GPS sensor (no GPS_RAW_INT yet)" : "");
      const q = v.link_quality || {};
      c[8].className = q.state === "ok" ? "" : (q.state ? "st-lost" : "");
      const ll = position ? position(v) : null;
      c[0].title = ll ? latLonText(ll[0], ll[1]) : "";
    });
    for (const row of Array.from(tbody.rows)) {
      if (!seen.has(row.dataset.id)) row.remove();
    }
  }

  window.floeGeo = { frame, zoomFor, Basemap, latLonText, updatePanel, gpsText, gpsWarning };
})();
