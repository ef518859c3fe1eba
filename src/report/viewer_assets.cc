// The report's style sheet; its viewer script is viewer.js beside this file,
// compiled in as ReportViewerScript() by CMakeLists.txt (docs/report.md).
// The viewer is a classic script over three.js r111 (Debian's libjs-three: three.min.js,
// examples/js/loaders/GLTFLoader.js, examples/js/controls/OrbitControls.js)
// so the page works from file://, where ES modules and fetch() of local
// files are blocked. model.js sets BANMO_MODEL_GLB (the .glb as base64),
// BANMO_BONE_PALETTE (extract's bone colours, sRGB 0-255) and BANMO_MODEL_INFO.
// URL parameters: t=<seconds> (fixed animation time, paused: deterministic
// screenshots), anim=<index>, bones=1, weights=1, shot=1 (the viewer fills
// the window).
#include "banmo/report/report.h"

namespace banmo {

const char* ReportStyleSheet() {
  return R"CSS(body { font-family: sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222;
       padding: 0 1em; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; }
td, th { border: 1px solid #ccc; padding: 2px 8px; text-align: left; font-size: 0.92em; }
th { background: #f2f2f2; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.note { color: #555; font-size: 0.92em; }
.skipped li { color: #8a4b00; }
#viewer { width: 100%; height: 480px; background: #1e232a; position: relative; }
#viewer canvas { display: block; }
#viewer-controls { margin: 0.4em 0; display: flex; gap: 1em; align-items: center;
                   flex-wrap: wrap; }
#viewer-time { width: 260px; }
#viewer-status { color: #b00; }
body.shot { margin: 0; max-width: none; padding: 0; overflow: hidden; }
body.shot #viewer { position: fixed; left: 0; top: 0; width: 100vw; height: 100vh; z-index: 10; }
img.panel { max-width: 100%; image-rendering: pixelated; display: block; margin: 0.3em 0; }
.turntable img { width: 128px; height: auto; margin: 2px; }
svg.plot { background: #fff; margin: 0.3em 0; display: block; }
svg.plot text { font-size: 11px; fill: #333; }
svg.plot .title { font-size: 13px; font-weight: bold; }
svg.plot .ytick { text-anchor: end; } svg.plot .xtick, svg.plot .xlabel { text-anchor: middle; }
svg.plot .ylabel { text-anchor: middle; }
svg.plot .frame { fill: none; stroke: #999; } svg.plot .grid { stroke: #e4e4e4; }
pre { background: #f6f6f6; padding: 0.6em; overflow-x: auto; font-size: 0.85em; }
)CSS";
}

}  // namespace banmo
