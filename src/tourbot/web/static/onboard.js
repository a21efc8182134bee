// The robot's own touch screen (Burgard et al., section 6.2): choose a tour or an exhibit, talk to
// the robot (typed, or from an offline recognizer feeding the same box), hear it answer, and see
// its face: happy when the way is free, then neutral, then angry the longer it is blocked; the eyes
// look where the robot is heading.
import { Live, chatLine, getJSON, el } from "./live.js";

const $ = (id) => document.getElementById(id);
const MOODS = {
  happy: { brow: 0, mouth: "M 60 115 Q 100 140 140 115" },
  neutral: { brow: 0, mouth: "M 60 122 L 140 122" },
  angry: { brow: 10, mouth: "M 60 130 Q 100 105 140 130" },
};

function setFace(face) {
  const mood = MOODS[face.mood] ? face.mood : "neutral";
  $("face").dataset.mood = mood;
  const m = MOODS[mood];
  // Angry brows slant down towards the nose.
  $("brow-l").setAttribute("y2", 38 + m.brow);
  $("brow-r").setAttribute("y1", 38 + m.brow);
  $("mouth").setAttribute("d", m.mouth);
  // Gaze: left is positive (the robot's left is the viewer's right, facing it).
  const dx = -Math.sin(face.gaze) * 9;
  $("pupil-l").setAttribute("cx", 65 + dx);
  $("pupil-r").setAttribute("cx", 135 + dx);
}

function say(text, audio) {
  $("said").textContent = text;
  if (audio) {
    $("voice").src = audio;
    $("voice").play().catch(() => {});
  }
}

async function start() {
  const site = await getJSON("/api/site");
  const robot = new URLSearchParams(location.search).get("robot") || site.robots[0];
  $("title").textContent = `Welcome to ${site.name}!`;
  const live = new Live(robot, site.stream, {
    screen: "onboard",
    onStatus: (status) => {
      if (status.face) setFace(status.face);
      const exhibit = site.exhibits.find((e) => e.slug === status.nav.exhibit);
      $("state").textContent = exhibit ? `${status.nav.state}: ${exhibit.name}` : status.nav.state;
    },
    onSay: (message) => say(message.text, message.audio),
    onChat: (line) => chatLine($("chat-log"), line, "onboard"),
    onReply: (reply) => { if (reply.type === "error") say(reply.message, null); },
  });
  for (const t of site.tours) {
    $("tours").append(el("button", { "data-tour": t.slug, onclick: () => live.send({ type: "tour", tour: t.slug }) }, t.name));
  }
  for (const e of site.exhibits) {
    $("exhibits").append(el("button", { "data-exhibit": e.slug, onclick: () => live.send({ type: "exhibit", exhibit: e.slug }) }, e.name));
  }
  $("talk").addEventListener("submit", (event) => {
    event.preventDefault();
    const text = $("phrase").value.trim();
    if (text) live.send({ type: "say", text });
    $("phrase").value = "";
  });
  $("chat").addEventListener("submit", (event) => {
    event.preventDefault();
    const text = $("chat-text").value.trim();
    if (text) live.send({ type: "chat", text });
    $("chat-text").value = "";
  });
  $("hint").textContent = "Try: who are you? · what time is it? · give me a tour · show me the " +
    (site.exhibits[0] ? site.exhibits[0].name : "exhibit") + " · help";
  window.tourbot = { live, site };
}

start().catch((error) => say(`Cannot start: ${error.message}`, null));
