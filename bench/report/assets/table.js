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
  var box = document.getElementById("filter");
  if (box) box.addEventListener("input", function () {
    var words = box.value.toLowerCase().split(/\s+/).filter(Boolean);
    document.querySelectorAll("#summary tbody tr").forEach(function (row) {
      var text = row.textContent.toLowerCase();
      row.hidden = !words.every(function (w) { return text.indexOf(w) >= 0; });
    });
  });
  var wanted = /sort=(-?)([^&]+)/.exec(location.hash), summary = document.getElementById("summary");
  if (wanted && summary) Array.prototype.forEach.call(summary.tHead.rows[0].cells, function (th) {
    if (th.textContent === decodeURIComponent(wanted[2])) { th.click(); if (wanted[1]) th.click(); }
  });
})();
