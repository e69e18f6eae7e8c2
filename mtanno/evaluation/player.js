// The player of an mtanno report page (mtanno/evaluation/player.py, page.py): the selected
// document's motion as a stick figure of its rig's bones over a ground line, its rows as a
// timeline (click or drag to seek), its Δ curves; play, pause, speed, step by frames.
// Poses and curves come from the data files beside the page (data/HASH.js), loaded by an
// added script element when a document of theirs is selected: no fetch(), no network.
(function () {
  "use strict";
  var M = window.mtanno, data = M.data, D = data.docs, R = data.rows, FPS = data.fps;
  var ANGLE = 0.6;  // the figure is seen turned 0.6 rad about the vertical
  var SIDES = {l: "#1f5fbf", r: "#c0392b", c: "#333"};

  // ------------------------------------------------------------------ data files
  var waiting = new Map(), files = new Map(), decoded = new Map();
  window.mtannoChunk = function (name, entries) {
    var done = waiting.get(name);
    if (done) { waiting.delete(name); done(entries); }
  };

  function file(i) {  // a data file's entries (a promise); a failed load may be retried
    if (!files.has(i)) {
      files.set(i, new Promise(function (resolve, reject) {
        var name = data.chunks[i], s = document.createElement("script");
        waiting.set(name, resolve);
        s.src = data.folder + "/" + name + ".js";
        s.onerror = function () {
          files.delete(i);
          reject(new Error("cannot load " + s.src + " (the page needs its folder)"));
        };
        document.head.appendChild(s);
      }));
    }
    return files.get(i);
  }

  function inflate(b64) {  // base 64 → deflated bytes → ArrayBuffer
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    if (typeof DecompressionStream === "undefined") {
      return Promise.reject(new Error("this browser has no DecompressionStream (Chrome 80, Firefox 113, Safari 16.4 and later have)"));
    }
    var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Response(stream).arrayBuffer();
  }

  function undelta(buf, width) {  // int16 differences, value by value → frame-major values
    var v = new DataView(buf), frames = buf.byteLength / 2 / width, out = new Int16Array(frames * width);
    for (var c = 0; c < width; c++) {
      for (var f = 0, acc = 0; f < frames; f++) {
        acc = (acc + v.getInt16(2 * (c * frames + f), true)) << 16 >> 16;
        out[f * width + c] = acc;
      }
    }
    return {values: out, frames: frames};
  }

  M.docData = function (d) {  // {poses, posed, rig, curves} of a document (a promise)
    if (decoded.has(d)) return decoded.get(d);
    var p = file(D.chunk[d]).then(function (entries) {
      var e = entries[D.slot[d]], rig = data.rigs[D.rig[d]] || null, nc = data.curves ? data.curves.classes.length : 0;
      return Promise.all([e[0] && rig ? inflate(e[0]) : null, e[1] && nc ? inflate(e[1]) : null]).then(function (b) {
        var out = {rig: rig, poses: null, posed: 0, curves: null, curved: 0};
        if (b[0]) { var p = undelta(b[0], rig.joints * 3); out.poses = p.values; out.posed = p.frames; }
        if (b[1]) { var c = undelta(b[1], nc); out.curves = new Uint16Array(c.values.buffer); out.curved = c.frames; }
        return out;
      });
    });
    decoded.set(d, p);
    p.catch(function () { decoded.delete(d); });
    if (decoded.size > 64) decoded.delete(decoded.keys().next().value);  // a few dozen kept
    return p;
  };

  // ------------------------------------------------------------------ the player
  function Player(el) {
    this.el = el;
    this.figure = el.querySelector("canvas.figure");
    this.line = el.querySelector("canvas.timeline");
    this.curveCanvas = el.querySelector("canvas.curves");
    this.button = el.querySelector("button.play");
    this.where = el.querySelector(".where");
    this.note = el.querySelector(".note");
    this.doc = -1;
    this.frame = 1;
    this.frames = 1;
    this.motion = null;
    this.timer = null;
    this.stopAt = 0;
    this.speed = 1;
    this.token = 0;
    var self = this, dragging = false;
    this.button.addEventListener("click", function () { if (self.timer) self.pause(); else self.play(); });
    el.querySelector("button.back").addEventListener("click", function () { self.step(-1); });
    el.querySelector("button.fwd").addEventListener("click", function () { self.step(1); });
    el.querySelector("select.speed").addEventListener("change", function (ev) {
      self.speed = parseFloat(ev.target.value) || 1;
      if (self.timer) { var stop = self.stopAt; self.pause(); self.play(0, stop); }
    });
    function at(ev) {
      var r = self.line.getBoundingClientRect();
      return 1 + Math.floor((ev.clientX - r.left) / r.width * self.frames);
    }
    this.line.addEventListener("pointerdown", function (ev) {
      dragging = true;
      if (self.line.setPointerCapture && ev.pointerId !== undefined) {
        try { self.line.setPointerCapture(ev.pointerId); } catch (e) { /* a synthetic event */ }
      }
      self.pause();
      self.seek(at(ev));
    });
    this.line.addEventListener("pointermove", function (ev) { if (dragging) self.seek(at(ev)); });
    ["pointerup", "pointercancel"].forEach(function (k) {
      self.line.addEventListener(k, function () { if (dragging) { dragging = false; M.link(); } });
    });
    window.addEventListener("resize", function () { self.draw(); });
  }

  Player.prototype.show = function (d, frame) {
    if (d === this.doc) { if (frame) this.seek(frame); return; }
    this.halt();
    this.doc = d;
    this.frames = Math.max(1, D.frames[d]);
    this.motion = null;
    this.el.setAttribute("data-doc", D.name[d]);
    this.el.setAttribute("data-frames", String(this.frames));
    this.el.querySelector(".name").textContent = M.display(D.name[d]);
    this.el.querySelector(".len").textContent = M.seconds(this.frames) + ", " + this.frames + " frames";
    this.note.textContent = D.note[d] || (D.chunk[d] < 0 && data.motions ? "no motion for this document" : "");
    this.seek(frame || 1);
    var self = this, token = ++this.token, t0 = performance.now();
    if (D.chunk[d] < 0) { this.state("none"); this.shown(t0); return; }
    this.state("loading");
    M.docData(d).then(function (x) {
      if (token !== self.token) return;
      self.motion = x;
      self.fit();
      self.state(x.poses ? "ready" : "none");
      self.draw();
      self.shown(t0);
    }, function (err) {
      if (token !== self.token) return;
      self.note.textContent = err.message;
      self.state("error");
      self.shown(t0);
    });
  };

  Player.prototype.state = function (s) { this.el.setAttribute("data-state", s); };

  Player.prototype.shown = function (t0) {  // the event tests and benchmarks wait for
    this.el.dispatchEvent(new CustomEvent("mtanno:shown", {bubbles: true,
      detail: {doc: D.name[this.doc], state: this.el.getAttribute("data-state"), ms: performance.now() - t0}}));
  };

  Player.prototype.missing = function (name) {
    this.note.textContent = "no document named " + M.display(name) + " in this report";
  };

  Player.prototype.seek = function (f) {
    this.frame = Math.max(1, Math.min(this.frames, Math.round(f) || 1));
    this.el.setAttribute("data-frame", String(this.frame));
    this.draw();
  };

  Player.prototype.step = function (n) { this.pause(); this.seek(this.frame + n); M.link(); };

  // Plays from frame `from` (default: where it is) to `to` (default: the end, then again
  // from the start), at the chosen speed.
  Player.prototype.play = function (from, to) {
    if (this.doc < 0) return;
    if (from) this.seek(from);
    this.stopAt = to || 0;
    if (this.timer) return;
    if (!this.stopAt && this.frame >= this.frames) this.seek(1);
    var self = this, t0 = performance.now(), f0 = this.frame;
    this.button.textContent = "pause";
    this.timer = setInterval(function () {
      var f = f0 + Math.floor((performance.now() - t0) / 1000 * FPS * self.speed);
      if (self.stopAt && f >= self.stopAt) { self.seek(self.stopAt); self.halt(); return; }
      if (f > self.frames) { t0 = performance.now(); f0 = f = 1; }
      if (f !== self.frame) self.seek(f);
    }, 15);
  };

  Player.prototype.halt = function () {  // stops playing; false if it was not
    if (!this.timer) return false;
    clearInterval(this.timer);
    this.timer = null;
    this.stopAt = 0;
    this.button.textContent = "play";
    return true;
  };

  Player.prototype.pause = function () { if (this.halt()) M.link(); };

  Player.prototype.point = function (f, j) {  // the figure's (x, y) of joint j at frame f
    var m = this.motion, k = ((Math.min(f, m.posed) - 1) * m.rig.joints + j) * 3, q = data.quantum;
    var x = m.poses[k] * q, y = m.poses[k + 1] * q, z = m.poses[k + 2] * q;
    return [x * Math.cos(ANGLE) + z * Math.sin(ANGLE), y];
  };

  Player.prototype.fit = function () {  // one scale for the whole document
    var m = this.motion;
    if (!m || !m.poses) return;
    var lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
    for (var f = 1; f <= m.posed; f += Math.max(1, Math.floor(m.posed / 400))) {
      for (var j = 0; j < m.rig.joints; j++) {
        var p = this.point(f, j);
        for (var a = 0; a < 2; a++) { lo[a] = Math.min(lo[a], p[a]); hi[a] = Math.max(hi[a], p[a]); }
      }
    }
    this.box = {lo: lo, hi: hi};
  };

  Player.prototype.draw = function () {
    if (this.doc < 0) return;
    this.drawFigure();
    this.drawTimeline();
    this.drawCurves();
    this.status();
  };

  Player.prototype.drawFigure = function () {
    var b = M.fit(this.figure), c = b.c, m = this.motion, self = this, f = this.frame;
    c.clearRect(0, 0, b.w, b.h);
    if (!m || !m.poses) {
      c.fillStyle = "#999";
      c.font = "13px sans-serif";
      c.fillText(this.el.getAttribute("data-state") === "loading" ? "loading the motion…" : "no motion", 12, 22);
      return;
    }
    var lo = this.box.lo, hi = this.box.hi;
    var s = 0.88 * Math.min(b.w / Math.max(hi[0] - lo[0], 1e-3), b.h / Math.max(hi[1] - lo[1], 1e-3));
    var ox = b.w / 2 - s * (lo[0] + hi[0]) / 2, oy = b.h / 2 + s * (lo[1] + hi[1]) / 2;
    var ground = oy - s * lo[1];
    c.strokeStyle = "#bbb";
    c.lineWidth = 1;
    c.beginPath(); c.moveTo(0, ground); c.lineTo(b.w, ground); c.stroke();
    c.lineWidth = 3;
    c.lineCap = "round";
    m.rig.bones.forEach(function (bone) {
      var p = self.point(f, bone[0]), q = self.point(f, bone[1]);
      c.strokeStyle = SIDES[m.rig.sides.charAt(bone[1])] || SIDES.c;
      c.beginPath();
      c.moveTo(ox + s * p[0], oy - s * p[1]);
      c.lineTo(ox + s * q[0], oy - s * q[1]);
      c.stroke();
    });
  };

  Player.prototype.drawTimeline = function () {
    var lanes = Math.min(4, Math.max(1, M.rowsOf(this.doc).length ? 2 : 1));
    var h = 8 + 9 * lanes + (data.truth ? 8 : 0);
    this.line.style.height = h + "px";
    var b = M.fit(this.line, h), c = b.c;
    c.clearRect(0, 0, b.w, b.h);
    M.paint(c, this.doc, 0, 0, b.w, b.h, {maxLanes: 4, current: M.currentRow});
    c.fillStyle = "#000";
    c.fillRect((this.frame - 0.5) / this.frames * b.w - 1, 0, 2, b.h);
  };

  Player.prototype.drawCurves = function () {
    var cv = this.curveCanvas, m = this.motion, C = data.curves;
    cv.hidden = !(C && m && m.curves);
    if (cv.hidden) return;
    var b = M.fit(cv, 90), c = b.c, n = this.frames, k = C.classes.length, F = m.curved;
    var top = Math.min(1, Math.max(0.1, 3 * Math.max.apply(null, C.tau)));
    function y(v) { return b.h - 2 - Math.min(v, top) / top * (b.h - 4); }
    c.clearRect(0, 0, b.w, b.h);
    c.setLineDash([3, 3]);
    C.tau.forEach(function (t, i) {
      c.strokeStyle = t === C["default"] ? "#000" : M.colour(data.labels.indexOf(C.classes[i]));
      c.beginPath(); c.moveTo(0, y(t)); c.lineTo(b.w, y(t)); c.stroke();
    });
    c.setLineDash([]);
    for (var i = 0; i < k; i++) {
      c.strokeStyle = M.colour(data.labels.indexOf(C.classes[i]));
      c.beginPath();
      var pen = false;
      for (var f = 0; f < F; f++) {
        var v = m.curves[f * k + i];
        if (v === 65535) { pen = false; continue; }
        var px = (f + 0.5) / n * b.w, py = y(v * 1e-4);
        if (pen) c.lineTo(px, py); else c.moveTo(px, py);
        pen = true;
      }
      c.stroke();
    }
    c.fillStyle = "#000";
    c.fillRect((this.frame - 0.5) / n * b.w - 1, 0, 2, b.h);
  };

  Player.prototype.status = function () {
    var f = this.frame, here = [], m = this.motion, C = data.curves;
    M.rowsOf(this.doc).forEach(function (r) {
      if (R.start[r] <= f && f <= R.end[r]) {
        here.push(M.display(data.labels[R.label[r]]) + (R.conf[r] === null ? "" : " (confidence " + R.conf[r].toFixed(2) + ")"));
      }
    });
    var text = "frame " + f + " of " + this.frames + " (" + ((f - 1) / FPS).toFixed(2) + " s): " +
      (here.length ? here.join(", ") : "no label");
    if (C && m && m.curves && f <= m.curved) {
      var k = C.classes.length, best = [];
      for (var i = 0; i < k; i++) {
        var v = m.curves[(f - 1) * k + i];
        if (v !== 65535) best.push([v * 1e-4, C.classes[i]]);
      }
      best.sort(function (a, b) { return a[0] - b[0]; });
      text += " · Δ " + (best.length ? best.slice(0, 3).map(function (x) { return M.display(x[1]) + " " + x[0].toFixed(3); }).join(", ") : "none");
    }
    this.where.textContent = text;
  };

  M.player = new Player(document.querySelector("[data-mtanno-player]"));
})();
