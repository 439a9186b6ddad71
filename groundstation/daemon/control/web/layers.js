// floe live map: the tracker's layers. Loaded before app.js, which calls these.
// Search cells: squares shaded by their value (darker = more worth a look). Tracks by the
// status the daemon reports in state.tracks: confirmed filled (as every target always
// was), tentative hollow and dashed, prior (a listed, unverified iceberg) purple, dotted,
// with a diamond. A target the tracker does not list (no tracker, a known target) is drawn
// as confirmed.
(function () {
  "use strict";

  const num = (v) => typeof v === "number" && isFinite(v);

  const STYLE = {
    confirmed: { colour: null, dash: [], fill: true, marker: "dot" },
    tentative: { colour: "#c8691c", dash: [4, 4], fill: false, marker: "ring" },
    prior: { colour: "#7b3fa0", dash: [1.5, 3.5], fill: false, marker: "diamond" },
  };

  // id -> the tracker's view of it ({status, existence, ...}); empty without a tracker.
  function trackIndex(doc) {
    const out = new Map();
    for (const t of (doc && Array.isArray(doc.tracks)) ? doc.tracks : []) {
      if (t && t.id !== undefined && STYLE[t.status]) out.set(String(t.id), t);
    }
    return out;
  }

  function statusOf(index, id) {
    const view = index.get(String(id));
    return view ? view.status : "confirmed";
  }

  // The cells of doc.search_cells as squares; the largest value is the darkest.
  function drawSearch(ctx, doc, toScreen, scale) {
    const cells = (doc && Array.isArray(doc.search_cells)) ? doc.search_cells : [];
    let top = 0;
    for (const c of cells) if (num(c.value_m2)) top = Math.max(top, c.value_m2);
    let drawn = 0;
    for (const c of cells) {
      if (!num(c.x_m) || !num(c.y_m) || !num(c.size_m) || c.size_m <= 0) continue;
      const [sx, sy] = toScreen(c.x_m - c.size_m / 2, c.y_m + c.size_m / 2);
      const side = c.size_m * scale;
      const share = top > 0 && num(c.value_m2) ? Math.max(0, c.value_m2) / top : 0;
      ctx.fillStyle = "rgba(31, 95, 191, " + (0.06 + 0.44 * share).toFixed(3) + ")";
      ctx.fillRect(sx, sy, side, side);
      ctx.strokeStyle = "rgba(31, 95, 191, 0.35)";
      ctx.lineWidth = 0.5;
      ctx.strokeRect(sx, sy, side, side);
      drawn += 1;
    }
    return drawn;
  }

  function marker(ctx, kind, sx, sy, colour) {
    ctx.setLineDash([]);
    if (kind === "diamond") {
      ctx.beginPath();
      ctx.moveTo(sx, sy - 6); ctx.lineTo(sx + 6, sy); ctx.lineTo(sx, sy + 6); ctx.lineTo(sx - 6, sy);
      ctx.closePath();
      ctx.fillStyle = "#ffffff"; ctx.fill();
      ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.stroke();
    } else if (kind === "ring") {
      ctx.beginPath(); ctx.arc(sx, sy, 4.5, 0, 2 * Math.PI);
      ctx.strokeStyle = colour; ctx.lineWidth = 1.5; ctx.stroke();
    } else {
      ctx.beginPath(); ctx.arc(sx, sy, 3.5, 0, 2 * Math.PI);
      ctx.fillStyle = colour; ctx.fill();
    }
  }

  // A track the page has no target entry for: a circle of 2 standard deviations.
  function drawBareTrack(ctx, t, toScreen, scale) {
    if (!num(t.x_m) || !num(t.y_m)) return false;
    const style = STYLE[t.status];
    const colour = style.colour || "#2e7d4f";
    const [sx, sy] = toScreen(t.x_m, t.y_m);
    const r = num(t.sigma_m2) ? 2 * Math.sqrt(Math.max(0, t.sigma_m2) / 2) * scale : 0;
    ctx.beginPath(); ctx.arc(sx, sy, Math.max(4, r), 0, 2 * Math.PI);
    ctx.setLineDash(style.dash);
    if (style.fill) { ctx.fillStyle = colour + "22"; ctx.fill(); }
    ctx.strokeStyle = colour; ctx.lineWidth = 1.2; ctx.stroke();
    marker(ctx, style.marker, sx, sy, colour);
    return true;
  }

  // "9 confirmed · 3 tentative · 1 prior · 100 search cells" (the Targets heading).
  function countsText(doc) {
    const counts = doc && doc.track_counts;
    const cells = (doc && Array.isArray(doc.search_cells)) ? doc.search_cells.length : 0;
    if (!counts || typeof counts !== "object") return cells ? cells + " search cells" : "";
    const parts = ["confirmed", "tentative", "prior"]
      .map((s) => (num(counts[s]) ? counts[s] : 0) + " " + s);
    if (cells) parts.push(cells + " search cells");
    return parts.join(" · ");
  }

  window.floeLayers = { STYLE, trackIndex, statusOf, drawSearch, drawBareTrack, marker,
                        countsText };
})();
