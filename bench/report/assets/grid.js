document.querySelectorAll('input.diff-toggle').forEach(function (box) {
  box.addEventListener('change', function () {
    document.getElementById(box.dataset.grid).classList.toggle('show-diff', box.checked);
  });
});
