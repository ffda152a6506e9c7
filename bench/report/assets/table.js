/* bench report: sortable and filterable tables */
(function () {
  function key(cell) {
    var text = cell ? cell.textContent.trim() : "", n = Number(text);
    return text === "" ? null : isNaN(n) ? text.toLowerCase() : n;
  }
  function compare(a, b) {
    if (typeof a !== typeof b) return typeof a === "number" ? -1 : 1;
    return a < b ? -1 : a > b ? 1 : 0;
  }
  function sortBy(table, th, i) {
    var up = th.getAttribute("aria-sort") !== "ascending", body = table.tBodies[0];
    Array.prototype.forEach.call(th.parentNode.cells, function (h) { h.removeAttribute("aria-sort"); });
    th.setAttribute("aria-sort", up ? "ascending" : "descending");
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (r, s) {
      var a = key(r.cells[i]), b = key(s.cells[i]);
      if (a === null || b === null) return (a === null) - (b === null);
      return up ? compare(a, b) : compare(b, a);
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  document.querySelectorAll("table.sortable").forEach(function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, i) {
      th.addEventListener("click", function () { sortBy(table, th, i); });
    });
  });
  /* the filter box: a plain word must appear somewhere in the row, a word
     "column:text" (model:torus faces:655) in that column's cell */
  var box = document.getElementById("filter");
  function matcher(word, names) {
    var at = word.indexOf(":"), column = at > 0 ? names.indexOf(word.slice(0, at)) : -1;
    var text = column >= 0 ? word.slice(at + 1) : word;
    return function (row) {
      var where = column >= 0 ? row.cells[column] : row;
      return !!where && where.textContent.toLowerCase().indexOf(text) >= 0;
    };
  }
  if (box) box.addEventListener("input", function () {
    var summary = document.getElementById("summary");
    var names = Array.prototype.map.call(summary.tHead.rows[0].cells, function (th) {
      return (th.dataset.column || th.textContent).trim().toLowerCase();
    });
    var tests = box.value.toLowerCase().split(/\s+/).filter(Boolean).map(function (w) {
      return matcher(w, names);
    });
    Array.prototype.forEach.call(summary.tBodies[0].rows, function (row) {
      row.hidden = !tests.every(function (test) { return test(row); });
    });
  });
  /* the columns toggle: the key columns, or every column */
  document.querySelectorAll("input.all-columns").forEach(function (toggle) {
    toggle.addEventListener("change", function () {
      document.getElementById(toggle.dataset.table).classList.toggle("all", toggle.checked);
    });
  });
  var wanted = /sort=(-?)([^&]+)/.exec(location.hash), summary = document.getElementById("summary");
  if (wanted && summary) Array.prototype.forEach.call(summary.tHead.rows[0].cells, function (th) {
    if (th.textContent === decodeURIComponent(wanted[2])) { th.click(); if (wanted[1]) th.click(); }
  });
})();
