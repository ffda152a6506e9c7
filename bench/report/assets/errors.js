/* bench report: any script error (or a promise nobody handled) shown at the top of the page */
(function () {
  var pending = [];
  function flush() {
    if (!pending.length || !document.body) return;  /* still in <head>: shown later */
    var pre = document.getElementById("script-errors");
    if (!pre) {
      pre = document.createElement("pre");
      pre.id = "script-errors";
      pre.setAttribute("role", "alert");
      document.body.insertBefore(pre, document.body.firstChild);
    }
    pre.textContent += pending.join("");
    pending = [];
  }
  function show(text) {
    pending.push("script error: " + text + "\n");
    flush();
  }
  document.addEventListener("DOMContentLoaded", flush);
  window.addEventListener("error", function (e) {
    show(e.message + (e.filename ? " (" + e.filename + ":" + e.lineno + ")" : ""));
  });
  window.addEventListener("unhandledrejection", function (e) {
    show(String(e.reason && e.reason.message || e.reason));
  });
})();
