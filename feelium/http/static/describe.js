// Events as sentences for the wearer: what happened, said as a person would, instead of the JSON envelope.
// A describer returns null for events that would only flood the list (a contact's moves, drawing strokes,
// presence updates): those still move the markers, they are just not news.

// Where on the skin a u, v is, in words (thirds of the sensitive patch, from the wearer's side).
export function skinPlace(u, v) {
  const row = v < 1 / 3 ? "top" : v > 2 / 3 ? "bottom" : "middle";
  const col = u < 1 / 3 ? "left" : u > 2 / 3 ? "right" : "centre";
  if (row === "middle" && col === "centre") return "the middle of the skin";
  if (row === "middle") return `the ${col} of the skin`;
  if (col === "centre") return `the ${row} of the skin`;
  return `the ${row} ${col} of the skin`;
}

const REGIONS = { head: "head", cheek_left: "left cheek", cheek_right: "right cheek", palm_zone: "palm area" };
const regionName = (r) => REGIONS[r] || (r ? r.replace(/_/g, " ") : "skin");
const seconds = (s) => `${s.toFixed(1)} s`;

function bearing(azimuth, elevation) {
  const az = Math.round(Math.abs(azimuth));
  const side = az < 10 ? "straight ahead" : `${az}\u00b0 to your ${azimuth < 0 ? "left" : "right"}`;
  const height = elevation > 15 ? ", above you" : elevation < -15 ? ", below you" : "";
  return side + height;
}

const INTERACTIONS = {
  greeting_pat: { pat: (e) => `The partner patted the ${regionName(e.region)}${e.taps > 1 ? ` (${e.taps} pats)` : ""}.` },
  palm_to_palm: {
    wearer: () => "You raised your palm; it waits on the skin for the partner's.",
    partner: () => "The partner's palm rests on the skin.",
    merge: () => "Your palms met.",
    end: (e) => (e.who === "wearer" ? "You lowered your palm." : "The partner took their palm away."),
  },
  peck: {
    bloom: (e) => `The partner gave a peck on the ${regionName(e.region)}.`,
    returned: (e) => `Your heart went back to the ${regionName(e.region)}.`,
  },
  drawing: {
    start: () => "The partner started drawing on the skin: guess what it is.",
    stroke: () => null,
    stroke_end: () => null,
    wrong_guess: (e) => `Not "${e.guess}": keep guessing.`,
    no_round: (e) => `You guessed "${e.guess}", but nobody is drawing.`,
    ignite: (e) => `Right, it was "${e.word}": the drawing lights up.`,
    end: (e) => (e.reason === "idle" ? `The drawing was abandoned${e.word ? ` (it was "${e.word}")` : ""}.` : "The drawing ended."),
  },
  hug: { start: () => "The partner is hugging the blimp.", end: () => "The hug ended." },
  invite: {
    shimmer: () => "You invited the partner with a shimmer.",
    accepted: () => "The partner accepted your invitation.",
  },
};

const ACTIONS = {
  heart: () => "You sent a heart.",
  palm_raise: () => "You raised your palm.",
  palm_lower: () => "You lowered your palm.",
  shimmer: () => "You sent a shimmer.",
  guess: (e) => `You guessed "${e.word}".`,
};

// Remembers when each contact started, to say how long it lasted.
export class Describer {
  constructor() { this.downAt = new Map(); }

  describe(item) {
    const e = item.event || {};
    switch (item.type) {
      case "touch": return this.touch(e);
      case "presence":
        if (e.phase === "approach") return `Someone came near, ${bearing(e.azimuth_deg, e.elevation_deg)}.`;
        if (e.phase === "leave") return "The person near the blimp went away.";
        return null;
      case "interaction": {
        const say = INTERACTIONS[e.name]?.[e.phase];
        return say ? say(e) : `${e.name.replace(/_/g, " ")}: ${e.phase.replace(/_/g, " ")}.`;
      }
      case "wearer_action": return (ACTIONS[e.action] || (() => `You did "${e.action}".`))(e);
      case "reset": return "The link missed some events; the view was redrawn from the blimp's current state.";
      default: return `Something new happened (${item.type}).`;
    }
  }

  touch(e) {
    if (e.phase === "down") {
      this.downAt.set(e.id, e.t);
      return `The partner touched ${skinPlace(e.u, e.v)}.`;
    }
    if (e.phase !== "up") return null;
    const t0 = this.downAt.get(e.id);
    this.downAt.delete(e.id);
    const place = skinPlace(e.u, e.v), lasted = t0 === undefined ? "" : ` after ${seconds(e.t - t0)}`;
    if (e.kind === "tap") return `It was a tap on ${place}.`;
    if (e.kind === "swipe") return `The partner swiped, ending at ${place}${lasted}.`;
    if (e.kind === "hold") return `The partner held ${place} and let go${lasted}.`;
    return `The partner let go of ${place}${lasted}.`;
  }
}
