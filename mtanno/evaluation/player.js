// The players and the review list of an mtanno report page (mtanno/evaluation/player.py).
// Reads the JSON of <script id="mtanno-data">; no file and no network.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("mtanno-data").textContent);
  var players = {};
  var FPS = 30, ANGLE = 0.6;  // frames per second; view turned 0.6 rad about the vertical

  function decode(text) {  // base 64 → Int16Array (little-endian)
    var bin = atob(text), out = new Int16Array(bin.length >> 1);
    for (var i = 0; i < out.length; i++) {
      out[i] = bin.charCodeAt(2 * i) | (bin.charCodeAt(2 * i + 1) << 8);
    }
    return out;
  }

  function lanes(segments) {  // greedy lanes so that overlapping segments stay visible
    var ends = [], out = [];
    segments.forEach(function (s) {
      var lane = 0;
      while (lane < ends.length && ends[lane] >= s[0]) lane++;
      ends[lane] = s[1];
      out.push(lane);
    });
    return {lane: out, count: Math.max(1, ends.length)};
  }

  function Player(el) {
    var doc = data.documents[el.getAttribute("data-doc")];
    this.el = el;
    this.frames = doc.frames;
    this.posed = doc.posed;
    this.q = decode(doc.poses);
    this.segments = doc.segments;
    this.lanes = lanes(this.segments);
    this.figure = el.querySelector("canvas.figure");
    this.line = el.querySelector("canvas.timeline");
    this.button = el.querySelector("button.play");
    this.text = el.querySelector(".where");
    this.frame = 1;
    this.timer = null;
    this.stop = null;
    this.line.height = 6 + 10 * this.lanes.count;
    this.fit();
    var self = this;
    this.button.addEventListener("click", function () {
      if (self.timer) self.pause(); else self.play();
    });
    this.line.addEventListener("click", function (ev) {
      var r = self.line.getBoundingClientRect();
      self.seek(1 + Math.floor((ev.clientX - r.left) / r.width * self.frames));
    });
    this.seek(1);
  }

  Player.prototype.point = function (f, j) {  // screen-space (x, y) of joint j, frame f
    var k = (Math.min(f, this.posed) - 1) * data.joints * 3 + 3 * j, q = data.quantum;
    var x = this.q[k] * q, y = this.q[k + 1] * q, z = this.q[k + 2] * q;
    return [x * Math.cos(ANGLE) + z * Math.sin(ANGLE), y];
  };

  Player.prototype.fit = function () {  // one scale for the whole document
    var lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
    for (var f = 1; f <= this.posed; f += Math.max(1, Math.floor(this.posed / 400))) {
      for (var j = 0; j < data.joints; j++) {
        var p = this.point(f, j);
        for (var a = 0; a < 2; a++) {
          lo[a] = Math.min(lo[a], p[a]);
          hi[a] = Math.max(hi[a], p[a]);
        }
      }
    }
    var w = this.figure.width, h = this.figure.height;
    this.scale = 0.9 * Math.min(w / Math.max(hi[0] - lo[0], 1e-3), h / Math.max(hi[1] - lo[1], 1e-3));
    this.origin = [w / 2 - this.scale * (lo[0] + hi[0]) / 2, h / 2 + this.scale * (lo[1] + hi[1]) / 2];
    this.ground = lo[1];
  };

  Player.prototype.labels = function () {
    var f = this.frame;
    return this.segments.filter(function (s) { return s[0] <= f && f <= s[1]; })
      .map(function (s) { return s[2]; });
  };

  Player.prototype.draw = function () {
    var c = this.figure.getContext("2d"), self = this, f = this.frame;
    c.clearRect(0, 0, this.figure.width, this.figure.height);
    function xy(p) { return [self.origin[0] + self.scale * p[0], self.origin[1] - self.scale * p[1]]; }
    c.strokeStyle = "#bbb";
    c.beginPath();
    var g = xy([0, this.ground]);
    c.moveTo(0, g[1]);
    c.lineTo(this.figure.width, g[1]);
    c.stroke();
    c.lineWidth = 3;
    data.bones.forEach(function (b, i) {
      var a = xy(self.point(f, b[0])), e = xy(self.point(f, b[1]));
      var side = data.names[b[1]].charAt(0);
      c.strokeStyle = side === "l" ? "#1f5fbf" : side === "r" ? "#c0392b" : "#333";
      c.beginPath();
      c.moveTo(a[0], a[1]);
      c.lineTo(e[0], e[1]);
      c.stroke();
    });
    c.lineWidth = 1;
    var t = this.line.getContext("2d"), W = this.line.width, n = this.frames;
    t.clearRect(0, 0, W, this.line.height);
    t.fillStyle = "#eee";
    t.fillRect(0, 0, W, this.line.height);
    this.segments.forEach(function (s, i) {
      t.fillStyle = data.colours[s[2]] || "#888";
      t.fillRect((s[0] - 1) / n * W, 3 + 10 * self.lanes.lane[i], Math.max(1, (s[1] - s[0] + 1) / n * W), 8);
    });
    t.fillStyle = "#000";
    t.fillRect((f - 0.5) / n * W - 1, 0, 2, this.line.height);
    var now = this.labels();
    this.text.textContent = "frame " + f + " of " + n + " (" + ((f - 1) / FPS).toFixed(2) + " s): " +
      (now.length ? now.join(", ") : "no label");
  };

  Player.prototype.seek = function (f) {
    this.frame = Math.max(1, Math.min(this.frames, Math.round(f)));
    this.el.setAttribute("data-frame", String(this.frame));
    this.draw();
  };

  Player.prototype.play = function (from, to) {
    if (from) this.seek(from);
    this.stop = to || null;
    if (this.timer) return;
    var self = this;
    this.button.textContent = "pause";
    this.timer = setInterval(function () {
      if (self.stop && self.frame >= self.stop) { self.pause(); return; }
      self.seek(self.frame >= self.frames ? 1 : self.frame + 1);
    }, 1000 / FPS);
  };

  Player.prototype.pause = function () {
    clearInterval(this.timer);
    this.timer = null;
    this.stop = null;
    this.button.textContent = "play";
  };

  // ---------------------------------------------------------------- the review list
  function rowOf(el) { while (el && el.tagName !== "TR") el = el.parentNode; return el; }

  function playRow(tr) {
    var p = players[tr.getAttribute("data-doc")];
    if (!p) return;
    var start = +tr.querySelector("input.start").value, end = +tr.querySelector("input.end").value;
    p.pause();
    p.seek(start);
    p.el.scrollIntoView({block: "center"});
    p.play(start, end);
  }

  function csvCell(v) {
    v = String(v);
    return /[",\n\r]/.test(v) ? '"' + v.replace(/"/g, '""') + '"' : v;
  }

  function truthCsv() {  // the accepted rows as a truth table (1-based frames at 30 Hz)
    var lines = ["doc,start,end,label,fps"], n = 0;
    document.querySelectorAll("tr.review").forEach(function (tr) {
      if (tr.querySelector("select.decision").value !== "accept") return;
      var label = tr.querySelector("input.label").value.trim();
      var start = parseInt(tr.querySelector("input.start").value, 10);
      var end = parseInt(tr.querySelector("input.end").value, 10);
      if (!label || !(start >= 1) || !(end >= start)) return;
      lines.push([tr.getAttribute("data-doc"), start, end, label, FPS].map(csvCell).join(","));
      n++;
    });
    return {text: lines.join("\n") + "\n", rows: n};
  }

  function count() {
    var t = truthCsv();
    var el = document.getElementById("truth-count");
    if (el) el.textContent = t.rows + " row(s) accepted";
    document.body.setAttribute("data-truth-rows", String(t.rows));
  }

  document.querySelectorAll("tr.review").forEach(function (tr) {
    tr.addEventListener("click", function (ev) {
      var tag = ev.target.tagName;
      if (tag !== "INPUT" && tag !== "SELECT" && tag !== "OPTION") playRow(tr);
    });
    tr.querySelectorAll("input").forEach(function (input) {
      input.addEventListener("change", function () {  // an edited row counts as accepted
        var d = tr.querySelector("select.decision");
        if (d.value === "") d.value = "accept";
        tr.className = "review " + d.value;
        count();
      });
    });
    tr.querySelector("select.decision").addEventListener("change", function (ev) {
      tr.className = "review " + ev.target.value;
      count();
    });
  });
  var rest = document.getElementById("accept-rest");
  if (rest) {
    rest.addEventListener("click", function () {
      document.querySelectorAll("tr.review").forEach(function (tr) {
        var d = tr.querySelector("select.decision");
        if (d.value === "") { d.value = "accept"; tr.className = "review accept"; }
      });
      count();
    });
  }
  var download = document.getElementById("download-truth");
  if (download) {
    download.addEventListener("click", function () {
      var t = truthCsv(), a = document.createElement("a");
      a.href = URL.createObjectURL(new Blob([t.text], {type: "text/csv"}));
      a.download = "truth.csv";
      document.body.appendChild(a);
      a.click();
      a.remove();
    });
  }

  document.querySelectorAll("[data-mtanno-player]").forEach(function (el) {
    players[el.getAttribute("data-doc")] = new Player(el);
  });
  count();
  if (location.hash === "#autoplay") {
    Object.keys(players).forEach(function (d) { players[d].play(); });
  }
})();
