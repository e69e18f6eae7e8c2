// Review on an mtanno report page (mtanno/evaluation/page.py): the selected document's rows
// in time order, accept / reject / relabel / move at the keyboard, decisions kept in the
// browser's storage for this report across reloads, "Download truth" as a truth CSV
// (doc,start,end,label,fps) that learn-mt, tune and evaluate --truth read.
(function () {
  "use strict";
  var M = window.mtanno, data = M.data, D = data.docs, R = data.rows, labels = data.labels;
  // a cell beginning so is a formula to a spreadsheet: such a row is not written
  var FORMULA = /^[=+\-@\t\r]/;
  var KEY = "mtanno-review:" + location.pathname;
  var decisions = new Map();  // row identity → {d: "accept"|"reject", label, start, end}
  var idents = [];
  var table = document.getElementById("mtanno-rows");
  var refused = document.getElementById("truth-refused");
  var storage = null;

  function ident(r) {  // a row is its document, frames and label: a rerun keeps decisions
    if (idents[r] === undefined) idents[r] = JSON.stringify([D.name[R.doc[r]], R.start[r], R.end[r], labels[R.label[r]]]);
    return idents[r];
  }
  M.decision = function (r) { var x = decisions.get(ident(r)); return x ? x.d : ""; };

  try {
    storage = window.localStorage;
    var saved = JSON.parse(storage.getItem(KEY) || "[]");
    if (Array.isArray(saved)) saved.forEach(function (e) { if (Array.isArray(e) && e.length === 2 && e[1]) decisions.set(String(e[0]), e[1]); });
  } catch (e) {
    storage = null;
  }

  function save() {
    if (!storage) return;
    var keep = [];
    for (var r = 0; r < R.doc.length; r++) if (decisions.has(ident(r))) keep.push([ident(r), decisions.get(ident(r))]);
    try { storage.setItem(KEY, JSON.stringify(keep)); } catch (e) { refused.textContent = "decisions not kept across reloads: " + e.message; }
  }

  function value(r, k) {  // a row's label, start or end: the reviewer's if edited
    var x = decisions.get(ident(r));
    if (x && x[k] !== undefined && x[k] !== null) return x[k];
    return k === "label" ? labels[R.label[r]] : R[k][r];
  }

  function decide(r, how, edit) {
    var x = decisions.get(ident(r)) || {};
    if (edit) Object.keys(edit).forEach(function (k) { x[k] = edit[k]; });
    x.d = how || (edit ? "accept" : "");
    if (!x.d && x.label === undefined && x.start === undefined && x.end === undefined) decisions.delete(ident(r));
    else decisions.set(ident(r), x);
  }

  function changed() {
    save();
    count();
    rows();
    M.refresh();
    M.player.drawTimeline();
    M.emit("decide");
  }

  // ------------------------------------------------------------------ the rows table
  function cell(tr, content) {
    var td = document.createElement("td");
    if (typeof content === "string") td.textContent = content; else td.appendChild(content);
    tr.appendChild(td);
  }
  function field(cls, v, type) {
    var i = document.createElement("input");
    i.className = cls;
    i.type = type;
    i.value = v;
    if (type === "number") i.min = "1";
    return i;
  }
  function button(act, text, title) {
    var b = document.createElement("button");
    b.type = "button";
    b.setAttribute("data-act", act);
    b.textContent = text;
    b.title = title;
    return b;
  }

  function rows() {  // the selected document's rows, in time order
    table.textContent = "";
    var d = M.current;
    if (d < 0) return;
    var match = new Set(M.matching(d));
    M.rowsOf(d).forEach(function (r) {
      var tr = document.createElement("tr"), how = M.decision(r), box = document.createElement("span");
      tr.setAttribute("data-row", String(r));
      tr.className = [how, r === M.currentRow ? "current" : "", match.has(r) ? "" : "other"].join(" ").trim();
      box.appendChild(field("start", value(r, "start"), "number"));
      box.appendChild(document.createTextNode("–"));
      box.appendChild(field("end", value(r, "end"), "number"));
      cell(tr, box);
      var lab = field("label", M.display(value(r, "label")), "text");
      lab.setAttribute("list", "mtanno-classes");
      cell(tr, lab);
      cell(tr, R.conf[r] === null ? "–" : R.conf[r].toFixed(2));
      var act = document.createElement("span");
      act.appendChild(button("accept", "✓", "accept (a)"));
      act.appendChild(button("reject", "✗", "reject (x)"));
      cell(tr, act);
      table.appendChild(tr);
    });
  }

  function rowOf(el) { var tr = el.closest ? el.closest("tr") : null; return tr ? parseInt(tr.getAttribute("data-row"), 10) : -1; }

  table.addEventListener("click", function (ev) {
    var r = rowOf(ev.target), act = ev.target.getAttribute && ev.target.getAttribute("data-act");
    if (r < 0) return;
    if (act) { M.setRow(r); decide(r, M.decision(r) === act ? "" : act); changed(); return; }
    if (ev.target.tagName !== "INPUT") M.setRow(r, true);
  });

  function refuse(input, why) {
    input.classList.add("bad");
    input.title = why;
    refused.textContent = why;
  }

  table.addEventListener("change", function (ev) {  // an edited row is accepted
    var input = ev.target, r = rowOf(input), v = input.value;
    if (r < 0) return;
    input.classList.remove("bad");
    if (input.classList.contains("label")) {
      if (v === M.display(value(r, "label"))) return;  // unchanged: a line break stays one
      v = v.trim();
      if (!v) return refuse(input, "a label cannot be empty");
      if (FORMULA.test(v)) return refuse(input, "a label beginning with =, +, -, @ would be a formula in a spreadsheet: not accepted");
      decide(r, "accept", {label: v});
    } else {
      var n = parseInt(v, 10), k = input.classList.contains("start") ? "start" : "end";
      var s = k === "start" ? n : value(r, "start"), e = k === "end" ? n : value(r, "end");
      if (!(s >= 1 && e >= s && e <= D.frames[R.doc[r]])) return refuse(input, "frames from 1 to " + D.frames[R.doc[r]] + ", the start not after the end");
      var edit = {};
      edit[k] = n;
      decide(r, "accept", edit);
    }
    refused.textContent = "";
    changed();
  });

  // ------------------------------------------------------------------ moving and deciding
  M.setRow = function (r, play) {
    M.currentRow = r;
    var d = R.doc[r];
    if (d !== M.current) M.select(d, {frame: value(r, "start"), hash: true});
    else { M.player.seek(value(r, "start")); M.link(); }
    rows();
    var tr = table.querySelector("tr.current");
    if (tr && tr.scrollIntoView) tr.scrollIntoView({block: "nearest"});
    if (play) M.player.play(value(r, "start"), value(r, "end"));
  };

  function move(step) {  // the next row of the documents shown, each in time order
    var shown = M.shown;
    if (!shown.length) return;
    var r = M.currentRow, d = r >= 0 ? R.doc[r] : M.current, pos = shown.indexOf(d);
    if (pos < 0) { pos = step > 0 ? -1 : shown.length; r = -1; }
    var list = pos >= 0 && pos < shown.length ? M.matching(shown[pos]) : [];
    var i = r >= 0 ? list.indexOf(r) : (step > 0 ? -1 : list.length);
    i += step;
    while (i < 0 || i >= list.length) {
      pos += step;
      if (pos < 0 || pos >= shown.length) return;
      list = M.matching(shown[pos]);
      i = step > 0 ? 0 : list.length - 1;
    }
    M.setRow(list[i]);
  }

  function moveDoc(step) {
    var shown = M.shown, pos = shown.indexOf(M.current) + step;
    if (pos >= 0 && pos < shown.length) { M.currentRow = -1; M.select(shown[pos], {frame: 1, hash: true}); }
  }

  function relabel() {
    var input = table.querySelector("tr.current input.label");
    if (input) { input.focus(); input.select(); }
  }

  document.addEventListener("keydown", function (ev) {
    var t = ev.target, tag = t && t.tagName;
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    if (tag === "INPUT" || tag === "SELECT" || tag === "TEXTAREA") {
      if (ev.key === "Escape" || (ev.key === "Enter" && tag === "INPUT" && t.closest && t.closest("#mtanno-rows"))) {
        if (ev.key === "Escape" && M.currentRow >= 0 && t.classList.contains("label")) t.value = M.display(value(M.currentRow, "label"));
        t.blur();  // Enter: the change is committed on leaving the field
        document.getElementById("mtanno-list").focus();
      }
      return;
    }
    var r = M.currentRow, k = ev.key;
    if (k === "j" || k === "ArrowDown") move(1);
    else if (k === "k" || k === "ArrowUp") move(-1);
    else if (k === "J") moveDoc(1);
    else if (k === "K") moveDoc(-1);
    else if ((k === "a" || k === "x" || k === "r") && r >= 0) { decide(r, k === "a" ? "accept" : "reject"); changed(); move(1); }
    else if (k === "u" && r >= 0) { decide(r, ""); changed(); }
    else if (k === "l" || k === "e") relabel();
    else if (k === " ") {
      if (M.player.timer) M.player.pause();
      else if (r >= 0) M.player.play(value(r, "start"), value(r, "end"));
      else M.player.play();
    } else if (k === "ArrowLeft" || k === "ArrowRight") M.player.step((k === "ArrowLeft" ? -1 : 1) * (ev.shiftKey ? 10 : 1));
    else if (k === "/") document.getElementById("mtanno-filter").focus();
    else return;
    ev.preventDefault();
  });

  // ------------------------------------------------------------------ truth
  function csvCell(v) {
    v = String(v);
    return /[",\n\r]/.test(v) ? '"' + v.replace(/"/g, '""') + '"' : v;
  }

  function truthCsv() {  // the accepted rows as a truth table (1-based frames at 30 Hz)
    var lines = ["doc,start,end,label,fps"], seen = new Set(), out = [], bad = 0;
    for (var r = 0; r < R.doc.length; r++) {
      if (M.decision(r) !== "accept") continue;
      var doc = D.name[R.doc[r]], label = value(r, "label");
      if (FORMULA.test(doc) || FORMULA.test(label)) { bad++; continue; }
      out.push([R.doc[r], value(r, "start"), value(r, "end"), doc, label]);
    }
    out.sort(function (a, b) { return a[0] - b[0] || a[1] - b[1] || a[2] - b[2]; });
    out.forEach(function (x) {
      var line = [x[3], x[1], x[2], x[4], data.fps].map(csvCell).join(",");
      if (!seen.has(line)) { seen.add(line); lines.push(line); }
    });
    return {text: lines.join("\n") + "\n", rows: lines.length - 1, refused: bad};
  }

  function count() {
    var t = truthCsv(), rejected = 0;
    for (var r = 0; r < R.doc.length; r++) if (M.decision(r) === "reject") rejected++;
    document.getElementById("truth-count").textContent = t.rows + " row(s) accepted, " + rejected +
      " rejected, of " + R.doc.length + (storage ? "" : " (not kept across reloads: no browser storage here)");
    document.body.setAttribute("data-truth-rows", String(t.rows));
    if (t.refused) {
      refused.textContent = t.refused + " accepted row(s) not written: their document or label begins with =, +, -, @ (a spreadsheet would take it for a formula); relabel them";
    }
  }

  document.getElementById("download-truth").addEventListener("click", function () {
    var t = truthCsv(), a = document.createElement("a");
    a.href = URL.createObjectURL(new Blob([t.text], {type: "text/csv"}));
    a.download = "truth.csv";
    document.body.appendChild(a);
    a.click();
    a.remove();
  });

  document.getElementById("mtanno-accept-above").addEventListener("click", function () {
    var p = parseFloat(document.getElementById("mtanno-accept-p").value);
    if (isNaN(p)) return;
    M.shown.forEach(function (d) {
      M.matching(d).forEach(function (r) {
        if (!M.decision(r) && R.conf[r] !== null && R.conf[r] >= p) decide(r, "accept");
      });
    });
    changed();
  });

  document.getElementById("mtanno-forget").addEventListener("click", function () {
    if (!window.confirm("Forget every decision on this report?")) return;
    decisions.clear();
    changed();
  });

  var options = document.createElement("datalist");  // the classes, for relabelling
  options.id = "mtanno-classes";
  labels.forEach(function (l) { var o = document.createElement("option"); o.value = l; options.appendChild(o); });
  document.body.appendChild(options);

  M.on("select", function () { rows(); });
  M.on("filter", function () { rows(); });
  M.apply();
  M.follow();
  count();
})();
