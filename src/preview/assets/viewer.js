// tessera's live viewer: follows the render's status by server-sent events (or, failing
// that, by polling /status), draws each new frame once it has loaded (so the old one stays
// until then: no flicker), outlines the tiles being rendered, and at the end offers the
// image file the render wrote. A small image is enlarged by a whole factor, pixels sharp.
"use strict";

const $ = (id) => document.getElementById(id);
const image = $("image");
const tiles = $("tiles");
let shown = 0;        // the frame version drawn
let loading = false;  // a frame is on its way
let wanted = 0;       // the newest frame version announced
let last = null;      // the newest status
let polling = null;
let pending = null;   // a status waiting for its frame to load
let kept = null;      // the finished image, kept in the page as a blob: URL
let keeping = false;  // it is being fetched
let events = null;    // the event stream
let trusted = false;  // its connection has sent this run's token
let gone = false;     // an answer came that is not this render's: the page asks no more

// This render's token: the server wrote it into the page, sends it with every answer and
// first in every event stream, and no request carries it. A program that takes the port once
// the server has gone (another user's) learns the key from the paths the page asks for, but
// not this: its answers are not taken, and the page stops asking.
const run = document.querySelector('meta[name="tessera-run"]').content;

function ours(response) {
  return run !== "" && response.headers.get("x-tessera-run") === run;
}

// An answer without this run's token: the server has gone and another program answers.
function foreign() {
  gone = true;
  if (events) events.close();
  if (polling) clearInterval(polling);
  pending = null;
  lost();
}

function clock(seconds) {
  if (seconds == null || !isFinite(seconds)) return "–";
  const s = Math.max(0, Math.round(seconds));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = s % 60;
  const two = (n) => String(n).padStart(2, "0");
  return h > 0 ? `${h}:${two(m)}:${two(r)}` : `${m}:${two(r)}`;
}

function number(n, digits) {
  return n == null || !isFinite(n) ? "–" : n.toFixed(digits);
}

// Loads the newest frame: only the rows that changed since the frame shown, when the server
// has that patch, else the whole frame.
async function loadFrame() {
  if (loading || wanted <= shown) return;
  loading = true;
  let again = false;
  try {
    const since = shown > 0 ? `&since=${shown}` : "";
    const r = await fetch(`frame.png?v=${wanted}${since}`, { cache: "no-store" });
    if (!r.ok) throw new Error(`frame: ${r.status}`);
    if (!ours(r)) {
      foreign();
      throw new Error("frame: not this render's");
    }
    const version = Number(r.headers.get("x-frame-version"));
    const rows = (r.headers.get("x-frame-rows") || "").split(",").map((a) => a.split("-").map(Number));
    const [width, height] = (r.headers.get("x-frame-size") || "").split(",").map(Number);
    const bitmap = await createImageBitmap(await r.blob());
    const whole = rows.length === 1 && rows[0][0] === 0 && rows[0][1] === height;
    if (!whole && (image.width !== width || image.height !== height || shown === 0)) {
      throw new Error("a patch for a frame this page does not hold");
    }
    // The status that announced this frame is shown with it: one repaint, not two.
    if (pending) {
      showText(pending);
      pending = null;
    }
    if (whole && (image.width !== width || image.height !== height)) {
      image.width = width;
      image.height = height;
      layout();
    }
    // The PNG holds the rows stacked in order.
    const ctx = image.getContext("2d");
    let from = 0;
    for (const [start, end] of rows) {
      ctx.drawImage(bitmap, 0, from, width, end - start, 0, start, width, end - start);
      from += end - start;
    }
    bitmap.close();
    shown = version;
    $("frame").classList.remove("empty");
    $("waiting").hidden = true;
    drawTiles();
    again = wanted > shown;
  } catch (e) {
    // Shown at once instead; the next status brings the next try.
    if (pending) showText(pending);
    pending = null;
  } finally {
    loading = false;
  }
  if (again) setTimeout(loadFrame, 0);
}

// Sizes the image in the stage: a whole number of device pixels per image pixel when it
// fits at least once (drawn sharp, no smoothing, even on a 1.5x screen), else shrunk to fit.
function layout() {
  const frame = $("frame");
  const actual = $("stage").classList.contains("actual");
  const dpr = window.devicePixelRatio || 1;
  const ratio = Math.min(frame.clientWidth / image.width, frame.clientHeight / image.height);
  const k = Math.floor(ratio * dpr) / dpr;
  const whole = !actual && k * dpr >= 1 && ratio >= 1;
  image.classList.toggle("whole", whole);
  if (whole) {
    image.style.width = `${image.width * k}px`;
    image.style.height = `${image.height * k}px`;
  } else {
    image.style.width = "";
    image.style.height = "";
  }
}

// Outlines the tiles being rendered: a few boxes laid over where the image is drawn.
function drawTiles() {
  const boxes = last && last.state === "rendering" ? last.tiles : [];
  const frame = $("frame").getBoundingClientRect();
  const box = image.getBoundingClientRect();
  const zoom = Math.min(box.width / image.width, box.height / image.height) || 1;
  const left = box.left - frame.left + (box.width - image.width * zoom) / 2;
  const top = box.top - frame.top + (box.height - image.height * zoom) / 2;
  const unit = zoom / (last ? last.frame.scale || 1 : 1);
  while (tiles.children.length > boxes.length) tiles.lastChild.remove();
  while (tiles.children.length < boxes.length) tiles.appendChild(document.createElement("div"));
  boxes.forEach(([x, y, w, h], i) => {
    const s = tiles.children[i].style;
    s.left = `${left + x * unit}px`;
    s.top = `${top + y * unit}px`;
    s.width = `${w * unit}px`;
    s.height = `${h * unit}px`;
  });
}

// Takes a new status: its text is shown at once, or with its frame when it brings one.
function show(status) {
  if (gone) return;
  last = status;
  wanted = Math.max(wanted, status.frame.version);
  if (status.frame.version > shown && !loading) {
    pending = status;
  } else {
    pending = null; // this text is newer than a pending one
    showText(status);
  }
  loadFrame();
}

function showText(status) {
  const a = status.about;
  $("scene").textContent = a.scene;
  document.title = `${status.percent.toFixed(0)}% · ${a.scene} · tessera`;
  const job = a.job === "whole image" ? "" : ` · ${a.job}`;
  $("settings").textContent =
    `${a.width}×${a.height} · ${a.spp} spp · depth ${a.max_depth} · seed ${a.seed} · ` +
    `${a.shading} · ${a.threads} thread${a.threads === 1 ? "" : "s"} · ${a.simd}${job} → ` +
    a.output;
  // Cut to a few lines by the style sheet: the whole text is the tooltip.
  $("scene").title = a.scene;
  $("settings").title = $("settings").textContent;
  const state = $("state");
  state.textContent = status.state;
  state.className = `state ${status.state}`;
  document.body.classList.toggle("finished", status.state === "finished");
  $("spp").textContent =
    status.spp_done === status.spp_max
      ? `${status.spp_done} / ${status.spp_total}`
      : `${status.spp_done}–${status.spp_max} / ${status.spp_total}`;
  $("percent").textContent = `${number(status.percent, 1)}%`;
  $("fill").style.width = `${Math.min(100, status.percent)}%`;
  $("progress").setAttribute("aria-valuenow", status.percent.toFixed(0));
  $("pass").textContent = `${status.pass} of ${status.passes}`;
  $("elapsed").textContent = clock(status.elapsed_s);
  $("eta").textContent = status.state === "rendering" ? clock(status.eta_s) : "–";
  $("sps").textContent = number(status.samples_per_sec / 1e6, 2) + " M";
  $("mrays").textContent = number(status.mrays_per_sec, 1);
  $("scale").textContent = status.frame.scale > 1 ? `shown at 1/${status.frame.scale} size` : "";
  offer(status);
  drawTiles();
}

// Offers the finished image: the file the render wrote, recipe and all. The page fetches it
// at once, takes it only with this run's token, and links to its own copy: the server goes
// when the render ends, and a link to it (even a held one's) would be followed to whoever
// holds the port when it is clicked, without the page seeing the answer.
function offer(status) {
  const link = $("download");
  const file = status.state === "finished" ? status.download : null;
  if (!file) {
    link.hidden = true;
    return;
  }
  link.download = file.name;
  link.title = `${file.name}, ${(file.bytes / 1024).toFixed(0)} KiB`;
  if (kept || keeping || gone) return;
  keeping = true;
  fetch("download", { cache: "no-store" })
    .then((r) => {
      if (r.ok && !ours(r)) foreign();
      return r.ok && !gone ? r.blob() : Promise.reject(new Error(`download: ${r.status}`));
    })
    .then((blob) => {
      kept = URL.createObjectURL(blob);
      link.href = kept;
      link.hidden = false;
    })
    .catch(() => {
      link.hidden = true;
    })
    .finally(() => {
      keeping = false;
    });
}

function poll() {
  if (polling || gone) return;
  polling = setInterval(async () => {
    try {
      const r = await fetch("status", { cache: "no-store" });
      if (r.ok && !ours(r)) return foreign();
      if (r.ok) show(await r.json());
    } catch (e) {
      lost();
    }
  }, 1000);
}

function lost() {
  // A link to the server would no longer work: only the page's own copy stays.
  if (!kept) $("download").hidden = true;
  const state = $("state");
  if (last && last.state === "finished") {
    state.textContent = "finished · viewer closed";
  } else {
    state.textContent = "connection lost";
    state.className = "state lost";
  }
}

function listen() {
  if (!("EventSource" in window)) return poll();
  events = new EventSource("events");
  let errors = 0;
  // Each connection of the stream shows the run's token before its statuses are taken.
  // Until it has, a link to the server's file is not offered: whoever answers may not be it.
  events.addEventListener("open", () => {
    trusted = false;
    if (!kept) $("download").hidden = true;
  });
  events.addEventListener("run", (e) => {
    trusted = e.data === run && run !== "";
    if (!trusted) return foreign();
    if (last) offer(last);
  });
  events.addEventListener("status", (e) => {
    if (!trusted) return foreign();
    errors = 0;
    const status = JSON.parse(e.data);
    show(status);
    // A render that has ended sends nothing more, and its server goes once this page has
    // the last frame and the file: asking again would ask whoever takes the port next.
    if (status.state !== "rendering" && !status.about.held) {
      events.close();
      $("state").textContent = `${status.state} · viewer closed`;
    }
  });
  events.onerror = () => {
    errors += 1;
    // A stream answered with anything but a stream (a 404, another type) is not retried by
    // the browser: the server that sent this page is not the one answering.
    if (errors >= 3 || events.readyState === EventSource.CLOSED) {
      events.close();
      lost();
      if (!last || last.state === "rendering") poll();
    }
  };
}

$("stage").addEventListener("click", () => {
  $("stage").classList.toggle("actual");
  layout();
  drawTiles();
});
// The stage changes size with the window and with the bars around it (a wrapped line of
// settings, the download link appearing).
new ResizeObserver(() => {
  layout();
  drawTiles();
}).observe($("frame"));
$("frame").classList.add("empty");
listen();
