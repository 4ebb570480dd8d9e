// Runs the viewer from a file opened from disk: the vendored modules travel as text in the page
// and are imported from blob URLs, their import specifiers pointed at one another.
(function () {
  const text = (id) => document.getElementById(id).textContent;
  const url = (source) => URL.createObjectURL(new Blob([source], { type: 'text/javascript' }));
  const core = url(text('rgmcad-three-core'));
  const three = url(text('rgmcad-three').split('"./three.core.min.js"').join(JSON.stringify(core)));
  const orbit = url(text('rgmcad-orbit').split("from 'three';").join(`from ${JSON.stringify(three)};`));
  const app = url(text('rgmcad-viewer')
    .split("from 'three/addons/controls/OrbitControls.js';").join(`from ${JSON.stringify(orbit)};`)
    .split("from 'three';").join(`from ${JSON.stringify(three)};`));
  import(app).catch((err) => {
    const box = document.querySelector('#rgmcad-replay .view');
    box.textContent = `The 3D view could not start here: ${err}`;
    document.getElementById('rgmcad-replay').dataset.error = String(err);
  });
})();
