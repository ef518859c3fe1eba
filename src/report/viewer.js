(function () {
  'use strict';
  var params = new URLSearchParams(window.location.search);
  var fixedTime = params.has('t') ? parseFloat(params.get('t')) : null;
  var statusEl = document.getElementById('viewer-status');
  function setStatus(text) { if (statusEl) statusEl.textContent = text; }
  function fail(message) {
    console.error('banmo viewer: ' + message);
    setStatus('viewer error: ' + message);
  }
  if (params.get('shot') === '1') document.body.classList.add('shot');
  if (typeof THREE === 'undefined' || !THREE.GLTFLoader || !THREE.OrbitControls) {
    fail('three.js did not load (three/ next to index.html missing?)');
    return;
  }
  if (typeof BANMO_MODEL_GLB !== 'string') {
    fail('model.js did not load');
    return;
  }
  var info = window.BANMO_MODEL_INFO || {fps: 10};
  var container = document.getElementById('viewer');
  var canvas = document.createElement('canvas');
  container.appendChild(canvas);
  var renderer;
  try {
    renderer = new THREE.WebGLRenderer({canvas: canvas, antialias: true,
                                        preserveDrawingBuffer: true});
  } catch (e) {
    fail('WebGL is not available: ' + (e && e.message ? e.message : e));
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.gammaOutput = true;  // r111: linear colours (COLOR_0) to sRGB
  renderer.gammaFactor = 2.2;
  var scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1e232a);
  var camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x303030, 0.6));
  var headlight = new THREE.DirectionalLight(0xffffff, 0.9);
  scene.add(headlight);
  scene.add(headlight.target);
  var controls = new THREE.OrbitControls(camera, canvas);
  controls.enableDamping = false;

  function resize() {
    var w = container.clientWidth || 640, h = container.clientHeight || 480;
    renderer.setSize(w, h, false);
    canvas.style.width = w + 'px';
    canvas.style.height = h + 'px';
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  window.addEventListener('resize', resize);
  resize();

  var binary = atob(BANMO_MODEL_GLB);
  var bytes = new Uint8Array(binary.length);
  for (var i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
  new THREE.GLTFLoader().parse(bytes.buffer, '', onLoad, function (e) {
    fail('glTF: ' + (e && e.message ? e.message : e));
  });

  function onLoad(gltf) {
    var model = gltf.scene;
    scene.add(model);
    var mesh = null, skinned = null;
    model.traverse(function (o) {
      if (o.isMesh && !mesh) mesh = o;
      if (o.isSkinnedMesh && !skinned) skinned = o;
    });
    if (!mesh) { fail('the glTF has no mesh'); return; }
    var geometry = mesh.geometry;
    geometry.computeBoundingSphere();
    var radius = geometry.boundingSphere.radius || 1;
    var material = mesh.material;
    var baseColors = geometry.getAttribute('color') || null;
    var boneColors = null;
    var skinIndex = geometry.getAttribute('skinIndex');
    var skinWeight = geometry.getAttribute('skinWeight');
    var palette = window.BANMO_BONE_PALETTE || [[200, 200, 200]];
    if (skinIndex && skinWeight) {
      // Colour of each vertex's dominant bone (extract's palette, as banmo
      // render's bone panel and skinning.ply), converted to linear.
      var n = skinIndex.count, colors = new Float32Array(3 * n);
      for (var v = 0; v < n; ++v) {
        var best = 0, bestWeight = -1;
        for (var k = 0; k < 4; ++k) {
          var w = skinWeight.getComponent ? skinWeight.getComponent(v, k) :
                  skinWeight.array[4 * v + k];
          if (w > bestWeight) {
            bestWeight = w;
            best = skinIndex.getComponent ? skinIndex.getComponent(v, k) :
                   skinIndex.array[4 * v + k];
          }
        }
        var c = palette[best % palette.length];
        for (var ch = 0; ch < 3; ++ch) colors[3 * v + ch] = Math.pow(c[ch] / 255, 2.2);
      }
      boneColors = new THREE.BufferAttribute(colors, 3);
    }

    // Bones: a marker per joint, and a line from the root to each.
    var bones = skinned ? skinned.skeleton.bones : [];
    var rootNode = model.getObjectByName('root') || model;
    var boneGroup = new THREE.Group();
    var markerGeometry = new THREE.SphereBufferGeometry(0.035 * radius, 12, 8);
    var markers = bones.map(function (bone, b) {
      var c = palette[b % palette.length];
      var m = new THREE.Mesh(markerGeometry, new THREE.MeshBasicMaterial({
        color: new THREE.Color(c[0] / 255, c[1] / 255, c[2] / 255), depthTest: false}));
      m.renderOrder = 10;
      boneGroup.add(m);
      return m;
    });
    var linePositions = new Float32Array(6 * Math.max(1, bones.length));
    var lineGeometry = new THREE.BufferGeometry();
    lineGeometry.setAttribute('position', new THREE.BufferAttribute(linePositions, 3));
    var lines = new THREE.LineSegments(lineGeometry, new THREE.LineBasicMaterial({
      color: 0xffffff, depthTest: false}));
    lines.renderOrder = 9;
    lines.frustumCulled = false;
    boneGroup.add(lines);
    boneGroup.visible = false;
    scene.add(boneGroup);

    var tmp = new THREE.Vector3(), rootPos = new THREE.Vector3();
    // The object's centre: the mean of the joints (the canonical mesh's
    // centre for a rigid model).
    function objectCentre(out) {
      model.updateMatrixWorld(true);
      if (bones.length === 0) {
        return out.copy(geometry.boundingSphere.center).applyMatrix4(mesh.matrixWorld);
      }
      out.set(0, 0, 0);
      bones.forEach(function (b) { out.add(b.getWorldPosition(tmp)); });
      return out.multiplyScalar(1 / bones.length);
    }
    function updateBones() {
      rootNode.getWorldPosition(rootPos);
      bones.forEach(function (b, k) {
        b.getWorldPosition(tmp);
        markers[k].position.copy(tmp);
        linePositions.set([rootPos.x, rootPos.y, rootPos.z, tmp.x, tmp.y, tmp.z], 6 * k);
      });
      lineGeometry.attributes.position.needsUpdate = true;
    }

    // Animations: one per video.
    var clips = gltf.animations || [];
    var mixer = new THREE.AnimationMixer(model);
    var action = null, clip = null;
    var select = document.getElementById('viewer-anim');
    var slider = document.getElementById('viewer-time');
    var playButton = document.getElementById('viewer-play');
    var timeLabel = document.getElementById('viewer-time-label');
    var playing = fixedTime === null && clips.length > 0;
    clips.forEach(function (c, k) {
      var o = document.createElement('option');
      o.value = String(k);
      o.textContent = c.name || ('animation ' + k);
      select.appendChild(o);
    });
    function setTime(t) {
      if (!action) return;
      action.time = Math.max(0, Math.min(t, clip.duration));
      slider.value = String(action.time);
      mixer.update(0);
    }
    function choose(k) {
      mixer.stopAllAction();
      if (clips.length === 0) return;
      clip = clips[Math.max(0, Math.min(k, clips.length - 1))];
      action = mixer.clipAction(clip);
      action.setLoop(THREE.LoopRepeat);
      action.play();
      slider.max = String(clip.duration);
      setTime(fixedTime !== null ? fixedTime : 0);
    }
    var startAnim = params.has('anim') ? parseInt(params.get('anim'), 10) || 0 : 0;
    select.value = String(Math.max(0, Math.min(startAnim, clips.length - 1)));
    choose(startAnim);
    select.addEventListener('change', function () { choose(parseInt(select.value, 10)); });
    playButton.textContent = playing ? 'pause' : 'play';
    playButton.addEventListener('click', function () {
      playing = !playing;
      playButton.textContent = playing ? 'pause' : 'play';
    });
    slider.addEventListener('input', function () {
      playing = false;
      playButton.textContent = 'play';
      setTime(parseFloat(slider.value));
    });

    var bonesBox = document.getElementById('viewer-bones');
    var weightsBox = document.getElementById('viewer-weights');
    bonesBox.checked = params.get('bones') === '1';
    weightsBox.checked = params.get('weights') === '1';
    if (bones.length === 0) bonesBox.disabled = true;
    if (!boneColors) weightsBox.disabled = true;
    function applyToggles() {
      boneGroup.visible = bonesBox.checked && bones.length > 0;
      var colors = weightsBox.checked && boneColors ? boneColors : baseColors;
      if (colors) {
        geometry.setAttribute('color', colors);
      } else {
        geometry.deleteAttribute('color');
      }
      material.vertexColors = colors ? THREE.VertexColors : THREE.NoColors;
      material.needsUpdate = true;
    }
    bonesBox.addEventListener('change', applyToggles);
    weightsBox.addEventListener('change', applyToggles);
    applyToggles();

    // The camera starts at the first video's camera (glTF origin, looking
    // down -z) aimed at the object, and follows the object as it moves.
    var centre = objectCentre(new THREE.Vector3());
    if (centre.length() > 2 * radius) {
      camera.position.set(0, 0, 0);
    } else {
      camera.position.copy(centre).add(new THREE.Vector3(0, 0, 3 * radius));
    }
    camera.near = radius / 100;
    camera.far = 100 * (centre.length() + radius);
    camera.updateProjectionMatrix();
    controls.target.copy(centre);
    controls.update();
    var last = centre.clone(), now = new THREE.Vector3();
    var clock = new THREE.Clock();
    var drawn = false;
    function loop() {
      requestAnimationFrame(loop);
      var dt = clock.getDelta();
      if (playing && action) {
        mixer.update(dt);
        slider.value = String(action.time);
      }
      objectCentre(now);
      camera.position.add(now.clone().sub(last));
      controls.target.add(now.clone().sub(last));
      last.copy(now);
      controls.update();
      headlight.position.copy(camera.position);
      headlight.target.position.copy(controls.target);
      updateBones();
      renderer.render(scene, camera);
      var t = action ? action.time : 0;
      timeLabel.textContent = 't = ' + t.toFixed(2) + ' s (frame ' +
          Math.round(t * info.fps) + ')';
      if (!drawn) {
        drawn = true;
        setStatus('');
        console.log('banmo viewer: drew ' + geometry.getAttribute('position').count +
                    ' vertices, ' + bones.length + ' bones, ' + clips.length +
                    ' animations at t = ' + t.toFixed(3) + ' s');
      }
    }
    loop();
  }
})();
