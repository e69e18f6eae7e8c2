// The archive view of an mtanno report page (mtanno/evaluation/page.py): one compact row
// per document in a virtualised list (only the rows in view exist), filtered, sorted and
// counted in the browser from the page's JSON. player.js and review.js hang on `mtanno`.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("mtanno-data").textContent);
  var D = data.docs, R = data.rows, T = data.truth, nDocs = D.name.length;
  var M = window.mtanno = {data: data, current: -1, currentRow: -1, shown: []};
  var hooks = {select: [], filter: [], decide: []};
  M.on = function (name, fn) { hooks[name].push(fn); };
  M.emit = function (name, arg) { hooks[name].forEach(function (fn) { fn(arg); }); };
  M.decision = function () { return ""; };  // review.js replaces it

  function group(docOf, n) {  // row indices per document (the JSON is by document, start)
    var out = [];
    for (var i = 0; i < n; i++) out.push([]);
    for (var r = 0; r < docOf.length; r++) out[docOf[r]].push(r);
    return out;
  }
  var rowsOf = group(R.doc, nDocs), truthOf = T ? group(T.doc, nDocs) : null;
  var byName = new Map();  // never an object keyed by a name: "__proto__" is a document too
  D.name.forEach(function (n, i) { byName.set(n, i); });
  M.rowsOf = function (d) { return rowsOf[d]; };
  M.truthOf = function (d) { return truthOf ? truthOf[d] : []; };
  M.docNamed = function (name) { return byName.has(name) ? byName.get(name) : -1; };
  M.colour = function (label) { return data.colours[label] || "#888888"; };
  M.seconds = function (frames) { return (frames / data.fps).toFixed(frames < 300 ? 1 : 0) + " s"; };
  M.display = function (text) { return String(text).replace(/\r\n|\r|\n/g, "⏎"); };

  // ------------------------------------------------------------------ filter and sort
  var input = document.getElementById("mtanno-filter");
  var confMin = document.getElementById("mtanno-conf-min");
  var confMax = document.getElementById("mtanno-conf-max");
  var sortBy = document.getElementById("mtanno-sort");
  var filter = {labels: [], names: [], notes: [], words: [], lo: 0, hi: 1, all: true};
  var matchingOf = new Map();  // document → its rows that match the filter, in time order

  function parse(text) {  // words; label:NAME, doc:TEXT, note:TEXT; "quoted words"
    var f = {labels: [], names: [], notes: [], words: []};
    var re = /(?:(label|doc|note):)?(?:"([^"]*)"|(\S+))?/gi, m;
    while ((m = re.exec(text)) !== null) {
      if (m[0] === "") { re.lastIndex++; continue; }
      var v = (m[2] !== undefined ? m[2] : m[3] || "").toLowerCase(), k = (m[1] || "").toLowerCase();
      (k === "label" ? f.labels : k === "doc" ? f.names : k === "note" ? f.notes : f.words).push(v);
    }
    return f;
  }

  function rowPasses(r) {
    var c = R.conf[r];
    if (!filter.all && !(c !== null && c >= filter.lo && c <= filter.hi)) return false;
    if (!filter.labels.length) return true;
    var lab = data.labels[R.label[r]].toLowerCase();
    return filter.labels.indexOf(lab) >= 0;
  }

  function docPasses(d) {
    var name = D.name[d].toLowerCase(), rows = rowsOf[d], i, j, ok;
    for (i = 0; i < filter.names.length; i++) if (name.indexOf(filter.names[i]) < 0) return false;
    for (i = 0; i < filter.notes.length; i++) {
      if (!D.note[d] || D.note[d].toLowerCase().indexOf(filter.notes[i]) < 0) return false;
    }
    var match = rows.filter(rowPasses);
    for (i = 0; i < filter.labels.length; i++) {
      var want = filter.labels[i];
      if (want === "none") { if (rows.length) return false; continue; }
      ok = false;
      for (j = 0; j < match.length && !ok; j++) ok = data.labels[R.label[match[j]]].toLowerCase() === want;
      if (!ok) return false;
    }
    if (!filter.all && !filter.labels.length && !match.length) return false;
    for (i = 0; i < filter.words.length; i++) {
      var w = filter.words[i];
      if (name.indexOf(w) >= 0) continue;
      ok = false;
      for (j = 0; j < match.length && !ok; j++) ok = data.labels[R.label[match[j]]].toLowerCase().indexOf(w) >= 0;
      if (!ok) return false;
    }
    matchingOf.set(d, match);
    return true;
  }
  M.matching = function (d) { return matchingOf.has(d) ? matchingOf.get(d) : []; };

  function leastConfidence(d) {
    var m = Infinity;
    M.matching(d).forEach(function (r) { if (R.conf[r] !== null && R.conf[r] < m) m = R.conf[r]; });
    return m;
  }

  M.apply = function () {
    var f = parse(input.value), lo = parseFloat(confMin.value), hi = parseFloat(confMax.value);
    f.lo = isNaN(lo) ? 0 : lo;
    f.hi = isNaN(hi) ? 1 : hi;
    f.all = f.lo <= 0 && f.hi >= 1;
    filter = f;
    matchingOf = new Map();
    var shown = [];
    for (var d = 0; d < nDocs; d++) if (docPasses(d)) shown.push(d);
    var by = sortBy.value;  // documents come in name order: ties stay so
    if (by === "conf") {
      var key = new Float64Array(nDocs);
      shown.forEach(function (d) { key[d] = leastConfidence(d); });
      shown.sort(function (a, b) { var x = key[a] - key[b]; return x === x && x !== 0 ? x : a - b; });
    } else if (by === "long") {
      shown.sort(function (a, b) { return D.frames[b] - D.frames[a] || a - b; });
    }
    M.shown = shown;
    list.setAttribute("data-mtanno-count", String(shown.length));
    document.getElementById("mtanno-shown").textContent = shown.length + " of " + nDocs + " documents";
    counts();
    render(true);
    M.emit("filter");
  };

  // ------------------------------------------------------------------ counts per class
  var countsEl = document.getElementById("mtanno-counts");
  function counts() {
    var rows = new Map(), docs = new Map();
    M.shown.forEach(function (d) {
      var seen = new Set();
      M.matching(d).forEach(function (r) {
        var l = R.label[r];
        rows.set(l, (rows.get(l) || 0) + 1);
        if (!seen.has(l)) { seen.add(l); docs.set(l, (docs.get(l) || 0) + 1); }
      });
    });
    var order = Array.from(rows.keys()).sort(function (a, b) { return rows.get(b) - rows.get(a) || a - b; });
    countsEl.textContent = "";
    order.forEach(function (l) {
      var b = document.createElement("button"), i = document.createElement("i"), name = data.labels[l];
      b.type = "button";
      b.setAttribute("data-label", name);
      b.title = "show only documents with this label";
      i.style.background = M.colour(l);
      b.appendChild(i);
      b.appendChild(document.createTextNode(M.display(name) + " " + rows.get(l) + " rows, " + docs.get(l) + " docs"));
      if (filter.labels.indexOf(name.toLowerCase()) >= 0) b.className = "on";
      countsEl.appendChild(b);
    });
  }
  countsEl.addEventListener("click", function (ev) {
    var b = ev.target.closest ? ev.target.closest("button") : null;
    if (!b) return;
    var name = b.getAttribute("data-label"), token = "label:" + (/[\s"]/.test(name) ? '"' + name.replace(/"/g, "") + '"' : name);
    var rest = input.value.replace(/(^|\s)label:("[^"]*"|\S+)/gi, "").trim();
    input.value = b.className === "on" ? rest : (rest ? rest + " " : "") + token;
    M.apply();
  });

  // ------------------------------------------------------------------ drawing segments
  var hatches = new Map();
  function hatch(c, colour) {  // rows without a confidence: hatched in their colour
    if (!hatches.has(colour)) {
      var p = document.createElement("canvas");
      p.width = p.height = 6;
      var g = p.getContext("2d");
      g.strokeStyle = colour;
      g.lineWidth = 2;
      g.beginPath(); g.moveTo(0, 6); g.lineTo(6, 0); g.stroke();
      hatches.set(colour, c.createPattern(p, "repeat"));
    }
    return hatches.get(colour);
  }

  function lanes(starts, ends, max) {  // greedy lanes so that overlapping rows stay visible
    var last = [], lane = [];
    for (var i = 0; i < starts.length; i++) {
      var k = 0;
      while (k < last.length && last[k] >= starts[i]) k++;
      if (k >= max) k = max - 1;
      last[k] = Math.max(last[k] || 0, ends[i]);
      lane.push(k);
    }
    return {lane: lane, count: Math.max(1, last.length)};
  }

  // Paints a document's rows (and truth) into a 2-D context in the box (x, y, w, h): each
  // row's opacity tells its confidence (hatched without one), rejected rows faint, accepted
  // ones underlined; `current` (a row) outlined. Returns the lanes used.
  M.paint = function (c, d, x, y, w, h, opts) {
    opts = opts || {};
    var n = Math.max(1, D.frames[d]), top = y;
    c.fillStyle = "#f0f0f0";
    c.fillRect(x, y, w, h);
    if (T && opts.truth !== false) {
      var th = Math.max(3, Math.round(h * 0.22));
      truthOf[d].forEach(function (s) {
        c.fillStyle = M.colour(T.label[s]);
        c.fillRect(x + (T.start[s] - 1) / n * w, y, Math.max(1, (T.end[s] - T.start[s] + 1) / n * w), th);
      });
      top = y + th + 1;
    }
    var rows = rowsOf[d], ls = lanes(rows.map(function (r) { return R.start[r]; }),
      rows.map(function (r) { return R.end[r]; }), opts.maxLanes || 3);
    var lh = (y + h - top) / ls.count;
    rows.forEach(function (r, i) {
      var colour = M.colour(R.label[r]), conf = R.conf[r], how = M.decision(r);
      var rx = x + (R.start[r] - 1) / n * w, rw = Math.max(1, (R.end[r] - R.start[r] + 1) / n * w);
      var ry = top + ls.lane[i] * lh;
      c.globalAlpha = how === "reject" ? 0.12 : conf === null ? 1 : 0.25 + 0.75 * Math.max(0, Math.min(1, conf));
      c.fillStyle = conf === null ? hatch(c, colour) : colour;
      c.fillRect(rx, ry, rw, lh - 1);
      c.globalAlpha = 1;
      if (how === "accept") { c.fillStyle = "#1b7d32"; c.fillRect(rx, ry + lh - 3, rw, 2); }
      if (r === opts.current) { c.strokeStyle = "#000"; c.lineWidth = 1.5; c.strokeRect(rx + 0.5, ry + 0.5, rw - 1, lh - 2); }
    });
    return ls.count;
  };

  M.fit = function (cv, height) {  // a canvas sized to its box, in CSS pixels
    var dpr = window.devicePixelRatio || 1, w = cv.clientWidth || 300, h = height || cv.clientHeight || 14;
    if (cv.width !== Math.round(w * dpr) || cv.height !== Math.round(h * dpr)) {
      cv.width = Math.round(w * dpr);
      cv.height = Math.round(h * dpr);
    }
    var c = cv.getContext("2d");
    c.setTransform(dpr, 0, 0, dpr, 0, 0);
    return {c: c, w: w, h: h};
  };

  // ------------------------------------------------------------------ the virtual list
  var list = document.getElementById("mtanno-list"), spacer = list.querySelector(".spacer");
  var ROW = 25, pool = [], pending = false;

  function makeRow() {
    var el = document.createElement("div");
    el.className = "doc";
    el.setAttribute("role", "option");
    ["name", "dur", "strip", "labs"].forEach(function (k) {
      var e = document.createElement(k === "strip" ? "canvas" : "span");
      e.className = k;
      el.appendChild(e);
    });
    return el;
  }

  function fill(el, d, i, redraw) {
    el.style.top = (i * ROW) + "px";
    var same = el._doc === d && !redraw;
    el._doc = d;
    el.setAttribute("data-mtanno-doc", D.name[d]);
    el.setAttribute("data-frames", String(D.frames[d]));
    el.setAttribute("aria-selected", d === M.current ? "true" : "false");
    el.className = d === M.current ? "doc current" : "doc";
    if (same) return;
    var kids = el.children, seen = new Set(), labs = [];
    kids[0].textContent = (D.note[d] ? "⚠ " : "") + M.display(D.name[d]);
    kids[0].title = D.name[d] + (D.note[d] ? "\n" + D.note[d] : "");
    kids[0].className = D.note[d] ? "name warn" : "name";
    kids[1].textContent = M.seconds(D.frames[d]);
    rowsOf[d].forEach(function (r) {
      if (!seen.has(R.label[r])) { seen.add(R.label[r]); labs.push(M.display(data.labels[R.label[r]])); }
    });
    kids[3].textContent = labs.length ? labs.join(", ") : "–";
    var box = M.fit(kids[2], 14);
    box.c.clearRect(0, 0, box.w, box.h);
    M.paint(box.c, d, 0, 0, box.w, box.h, {maxLanes: 2});
  }

  function render(redraw) {
    pending = false;
    var n = M.shown.length, top = list.scrollTop, h = list.clientHeight || 600;
    spacer.style.height = (n * ROW) + "px";
    var first = Math.max(0, Math.floor(top / ROW) - 4), last = Math.min(n, Math.ceil((top + h) / ROW) + 4);
    for (var i = first, k = 0; i < last; i++, k++) {
      if (!pool[k]) pool[k] = makeRow();
      if (pool[k].parentNode !== list) list.appendChild(pool[k]);
      fill(pool[k], M.shown[i], i, redraw);
    }
    for (; k < pool.length; k++) if (pool[k].parentNode) list.removeChild(pool[k]);  // only rendered rows exist
  }
  M.render = render;
  M.refresh = function () { render(true); };
  list.addEventListener("scroll", function () {
    if (!pending) { pending = true; requestAnimationFrame(function () { render(false); }); }
  });
  window.addEventListener("resize", function () { render(true); });
  list.addEventListener("click", function (ev) {
    var el = ev.target.closest ? ev.target.closest(".doc") : null;
    if (el) M.select(el._doc, {scroll: false, hash: true});
  });

  function scrollTo(d) {
    var i = M.shown.indexOf(d);
    if (i < 0) return;
    var top = i * ROW, h = list.clientHeight;
    if (top < list.scrollTop) list.scrollTop = top;
    else if (top + ROW > list.scrollTop + h) list.scrollTop = top + ROW - h;
  }

  // ------------------------------------------------------------------ selection, links
  M.select = function (d, opts) {
    opts = opts || {};
    if (!(d >= 0 && d < nDocs)) return;
    var changed = d !== M.current;
    M.current = d;
    if (changed && M.currentRow >= 0 && R.doc[M.currentRow] !== d) M.currentRow = -1;
    if (opts.scroll !== false) scrollTo(d);
    render(false);
    M.player.show(d, opts.frame || (changed ? 1 : 0));
    if (changed) M.emit("select", d);
    if (opts.hash) M.link();
  };

  M.link = function () {  // the address says what is shown: #doc=NAME&frame=F
    if (M.current < 0 || !history.replaceState) return;
    history.replaceState(null, "", "#doc=" + encodeURIComponent(D.name[M.current]) + "&frame=" + M.player.frame);
  };

  function fromHash() {  // #doc=NAME&frame=F, #autoplay; '+' is a plus, not a space
    var out = new Map();
    location.hash.replace(/^#/, "").split("&").forEach(function (part) {
      if (!part) return;
      var k = part.indexOf("="), key = k < 0 ? part : part.slice(0, k), v = k < 0 ? "" : part.slice(k + 1);
      try { out.set(decodeURIComponent(key), decodeURIComponent(v)); } catch (e) { out.set(key, v); }
    });
    return out;
  }

  M.follow = function () {
    var h = fromHash(), d = h.has("doc") ? M.docNamed(h.get("doc")) : -1;
    if (h.has("doc") && d < 0) {
      M.player.missing(h.get("doc"));
    } else if (d >= 0) {
      M.select(d, {frame: parseInt(h.get("frame"), 10) || 1});
    } else if (M.current < 0 && M.shown.length) {
      M.select(M.shown[0], {frame: 1});
    }
    if (h.has("autoplay") && M.current >= 0) M.player.play();
  };
  window.addEventListener("hashchange", M.follow);

  [input, confMin, confMax].forEach(function (e) { e.addEventListener("input", M.apply); });
  sortBy.addEventListener("change", M.apply);
})();
