/* bench report: 3D view of the LODs */
(function () {
  var active = null, meshes = {}, library = null;
  function loadScript(src) {
    return new Promise(function (resolve, reject) {
      var s = document.createElement("script");
      s.src = src;
      s.onload = function () { resolve(); };
      s.onerror = function () { reject(new Error("cannot load " + src + " (is the run folder whole?)")); };
      document.head.appendChild(s);
    });
  }
  function three(src) {
    if (!library) library = loadScript(src).then(function () {
      if (!window.THREE || !THREE.GLTFLoader || !THREE.OrbitControls)
        throw new Error(src + " did not define three.js");
      THREE.ColorManagement.enabled = false;  // colours as the protocol's images: no conversions
    });
    return library;
  }
  function glb(src, id) {  /* the parsed glTF of a wrapped GLB, once per page */
    if (!meshes[id]) meshes[id] = loadScript(src).then(function () {
      var text = (window.benchGlb || {})[id];
      if (typeof text !== "string") throw new Error(src + " holds no mesh");
      delete window.benchGlb[id];
      var bin = atob(text), bytes = new Uint8Array(bin.length);
      for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
      return new Promise(function (resolve, reject) {
        new THREE.GLTFLoader().parse(bytes.buffer, "", resolve, function (e) {
          reject(new Error("cannot read " + src + ": " + (e && e.message || e)));
        });
      });
    }).then(prepare);
    return meshes[id];
  }
  function prepare(gltf) {  /* the protocol's material on every primitive, a wireframe beside */
    var parts = [], faces = 0, textured = false;
    gltf.scene.traverse(function (o) { if (o.isMesh) parts.push(o); });
    parts.forEach(function (o) {
      var g = o.geometry, map = o.material.map || null;
      if (!g.getAttribute("normal")) g.computeVertexNormals();
      if (map) { map.colorSpace = THREE.NoColorSpace; textured = true; }
      o.userData.map = map;
      o.material = new THREE.MeshLambertMaterial({
        color: map ? 0xffffff : o.material.color, map: map, side: THREE.DoubleSide,
        vertexColors: !!g.getAttribute("color"),
        polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1});
      var wire = new THREE.Mesh(g, new THREE.MeshBasicMaterial({color: 0x1a1a1a, wireframe: true}));
      wire.visible = false;
      o.add(wire);
      o.userData.wire = wire;
      faces += (g.index ? g.index.count : g.getAttribute("position").count) / 3;
    });
    return {object: gltf.scene, parts: parts, faces: faces, textured: textured};
  }
  function Viewer(root) {
    var q = function (s) { return root.querySelector(s); };
    this.root = root; this.lod = q(".v3d-lod"); this.shading = q(".v3d-shading");
    this.texture = q(".v3d-texture"); this.wire = q(".v3d-wire"); this.stage = q(".v3d-stage");
    this.status = q(".v3d-status"); this.caption = q(".v3d-caption"); this.token = 0;
    var self = this;
    this.syncShading();
    q(".v3d-open").addEventListener("click", function () { self.open(); });
    this.lod.addEventListener("change", function () {  /* open: keep the reader's shading */
      if (self.renderer) self.show(); else self.syncShading();
    });
    [this.shading, this.texture, this.wire].forEach(function (c) {
      c.addEventListener("change", function () { if (self.renderer) { self.restyle(); self.draw(); } });
    });
    this.resize = function () { self.layout(); self.draw(); };
  }
  Viewer.prototype.syncShading = function () {  /* the shading the chosen job was evaluated with */
    var option = this.lod.options[this.lod.selectedIndex];
    if (option && option.getAttribute("data-shading")) this.shading.value = option.getAttribute("data-shading");
  };
  Viewer.prototype.fail = function (error) {
    this.root.setAttribute("data-status", "error");
    this.status.textContent = "3D view: " + (error && error.message || error);
  };
  Viewer.prototype.open = function () {
    var self = this;
    if (active && active !== this) active.close();
    active = this;
    this.root.setAttribute("data-status", "loading");
    this.status.textContent = "Loading three.js ...";
    return three(this.root.getAttribute("data-three")).then(function () {
      self.start();
      return self.show();
    }).catch(function (e) { self.fail(e); });
  };
  Viewer.prototype.start = function () {
    if (this.renderer) return;
    var renderer;
    try {
      renderer = new THREE.WebGLRenderer({antialias: true});
    } catch (e) {
      throw new Error("WebGL is not available in this browser, so nothing can be drawn (" + (e.message || e) + ")");
    }
    renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setScissorTest(true);
    this.stage.appendChild(renderer.domElement);
    this.renderer = renderer;
    this.camera = new THREE.PerspectiveCamera(60, 1, 0.01, 100);
    this.controls = new THREE.OrbitControls(this.camera, renderer.domElement);
    var self = this;
    this.controls.addEventListener("change", function () { self.draw(); });
    this.scenes = [0, 1].map(function () {
      var scene = new THREE.Scene();
      scene.background = new THREE.Color(0.5, 0.5, 0.5);
      scene.add(new THREE.AmbientLight(0xffffff, 0.1 * Math.PI));
      scene.userData.light = new THREE.PointLight(0xffffff, 0.9 * Math.PI, 0, 0);  // at the eye
      scene.add(scene.userData.light);
      return scene;
    });
    this.shown = [null, null];
    window.addEventListener("resize", this.resize);
    this.layout();
  };
  Viewer.prototype.show = function () {
    var self = this, option = this.lod.options[this.lod.selectedIndex], token = ++this.token;
    var get = function (name) { return option.getAttribute("data-" + name); };
    this.root.setAttribute("data-status", "loading");
    this.status.textContent = "Loading " + option.textContent + " ...";
    return Promise.all([glb(get("original"), get("original-id")), glb(get("lod"), get("lod-id"))]).then(function (both) {
      if (token !== self.token || !self.renderer) return;  // another choice came since, or closed
      var refit = self.shown[0] !== both[0];
      both.forEach(function (m, i) {
        if (self.shown[i]) self.scenes[i].remove(self.shown[i].object);
        self.scenes[i].add(m.object);
        self.shown[i] = m;
      });
      if (refit) self.fit(both[0]);
      self.texture.disabled = !(both[0].textured || both[1].textured);
      self.restyle();
      self.draw();
      self.root.setAttribute("data-faces", String(both[1].faces));
      self.root.setAttribute("data-original-faces", String(both[0].faces));
      self.root.setAttribute("data-status", "ready");
      self.status.textContent = "Left: the original, " + both[0].faces + " triangles. Right: " +
        option.textContent + ", " + both[1].faces + " triangles drawn. Drag to orbit, right-drag to pan, " +
        "wheel to zoom: both views share one camera. A light at the eye, 50 % gray background, as the protocol renders.";
      self.links(get("original-glb"), get("lod-glb"));
    }).catch(function (e) { if (token === self.token) self.fail(e); });
  };
  Viewer.prototype.links = function (original, lod) {
    var c = this.caption;
    c.textContent = "The meshes as GLB files (any glTF viewer opens them): ";
    [["original", original], ["this LOD", lod]].forEach(function (pair, i) {
      var a = document.createElement("a");
      a.href = pair[1];
      a.textContent = pair[0];
      if (i) c.appendChild(document.createTextNode(", "));
      c.appendChild(a);
    });
  };
  Viewer.prototype.fit = function (shown) {  /* the original's bounding sphere fills 90 % of the height */
    var c = new THREE.Box3().setFromObject(shown.object).getCenter(new THREE.Vector3());
    var r = 0, p = new THREE.Vector3();
    shown.parts.forEach(function (o) {
      var a = o.geometry.getAttribute("position");
      o.updateWorldMatrix(true, false);
      for (var i = 0; i < a.count; i++) r = Math.max(r, p.fromBufferAttribute(a, i).applyMatrix4(o.matrixWorld).distanceTo(c));
    });
    r = r || 1;
    this.camera.near = r * 0.02; this.camera.far = r * 20;
    this.camera.position.copy(c).add(new THREE.Vector3(0.6, 0.45, 1).normalize().multiplyScalar(2.2 * r));
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(c);
    this.controls.update();
  };
  Viewer.prototype.restyle = function () {
    var flat = this.shading.value === "flat", texture = this.texture.checked, wire = this.wire.checked;
    this.root.setAttribute("data-shading", this.shading.value);
    this.root.setAttribute("data-wireframe", String(wire));
    this.shown.forEach(function (m) {
      if (m) m.parts.forEach(function (o) {
        o.material.flatShading = flat;
        o.material.map = texture ? o.userData.map : null;
        o.material.needsUpdate = true;
        o.userData.wire.visible = wire;
      });
    });
  };
  Viewer.prototype.layout = function () {
    var width = Math.max(200, this.stage.clientWidth), height = Math.min(560, Math.round(width / 2));
    this.size = [width, height];
    this.renderer.setSize(width, height);
    this.camera.aspect = (width / 2 - 1) / height;
    this.camera.updateProjectionMatrix();
  };
  Viewer.prototype.draw = function () {
    if (!this.renderer) return;
    var w = this.size[0], h = this.size[1], half = Math.floor(w / 2), self = this;
    this.scenes.forEach(function (scene, i) {
      var x = i ? half + 1 : 0, width = i ? w - half - 1 : half - 1;
      scene.userData.light.position.copy(self.camera.position);
      self.renderer.setViewport(x, 0, width, h);
      self.renderer.setScissor(x, 0, width, h);
      self.renderer.render(scene, self.camera);
    });
  };
  Viewer.prototype.close = function () {
    if (!this.renderer) return;
    window.removeEventListener("resize", this.resize);
    this.controls.dispose();
    this.renderer.dispose();
    this.renderer.forceContextLoss();
    this.stage.removeChild(this.renderer.domElement);
    this.renderer = null;
    this.token++;
    this.root.setAttribute("data-status", "closed");
    this.status.textContent = "Closed: another model's 3D view is open (one at a time).";
  };
  var viewers = Array.prototype.map.call(document.querySelectorAll("div.viewer3d"),
                                         function (root) { return new Viewer(root); });
  function decode(text) {  /* a malformed % escape leaves the text as it is */
    try { return decodeURIComponent(text); } catch (e) { return text; }
  }
  function address() {  /* the fragment's key=value pairs, split on "&" (a bare key: ""); the first of a key counts */
    var found = Object.create(null);
    location.hash.replace(/^#/, "").split("&").forEach(function (part) {
      var at = part.indexOf("="), key = decode(at < 0 ? part : part.slice(0, at));
      if (key && !(key in found)) found[key] = at < 0 ? "" : decode(part.slice(at + 1));
    });
    return found;
  }
  var wanted = address();
  if ("view3d" in wanted && viewers.length) {
    var chosen = viewers.filter(function (v) {
      return v.root.getAttribute("data-model") === wanted.view3d;
    })[0] || viewers[0];
    var n = /^\d+$/.test(wanted.lod || "") ? Number(wanted.lod) : -1;
    var pick = n >= 0 ? chosen.lod.options[n] : null;
    if (pick && !pick.disabled) chosen.lod.selectedIndex = n;
    chosen.syncShading();
    if (wanted.shading === "flat" || wanted.shading === "smooth") chosen.shading.value = wanted.shading;
    if ("wireframe" in wanted) chosen.wire.checked = true;
    chosen.root.scrollIntoView();
    chosen.open();
  }
})();
