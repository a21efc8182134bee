"""The phrases the robot understands on site (Burgard et al., section 6.2).

"The software allows the definition of contexts, i.e., sets of phrases that are relevant in
certain situations. Depending on user input or depending on the task that is currently carried
out, the system can dynamically switch between the different contexts. The current system
includes 20 different phrases, that can be used to request information about the robot, the
exhibition site, or even the time and the weather."

Phrases arrive as text: typed on the touch screen, or from an offline recognizer when one is
installed. Matching is tolerant (a recognizer's small errors still match), limited to the phrases
of the active context.
"""

from __future__ import annotations

import difflib
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

__all__ = ["CONTEXTS", "PHRASES", "Phrase", "PhraseBook", "Reply"]

IDLE, TOUR, EXHIBIT = "idle", "tour", "exhibit"
CONTEXTS = (IDLE, TOUR, EXHIBIT)
_ALL = frozenset(CONTEXTS)
_AWAY = frozenset({TOUR, EXHIBIT})
_AT = frozenset({EXHIBIT})


@dataclass(frozen=True)
class Phrase:
    """Ways to say one thing, the contexts where it is heard, the action and the answer."""

    intent: str
    says: tuple[str, ...]
    answer: str
    contexts: frozenset[str] = _ALL
    action: str | None = None


@dataclass(frozen=True)
class Reply:
    intent: str
    text: str
    action: str | None = None
    argument: str | None = None
    context: str = IDLE


PHRASES: tuple[Phrase, ...] = (
    Phrase("hello", ("hello", "hi robot", "good morning"), "Hello! I am {robot}, your guide."),
    Phrase("who", ("who are you", "what is your name"), "I am {robot}, a tour-guide robot."),
    Phrase("origin", ("where are you from", "who built you"), "I was built to guide visitors at {site}."),
    Phrase("doing", ("what are you doing here", "what do you do"), "I guide visitors and remote guests."),
    Phrase("time", ("what time is it", "tell me the time"), "It is {time}."),
    Phrase("weather", ("how is the weather", "what is the weather like"), "Indoors it is always fine."),
    Phrase("site", ("where am i", "what is this place"), "You are at {site}."),
    Phrase("help", ("help", "what can i say"), "Ask me for a tour, an exhibit, or who I am."),
    Phrase("tours", ("which tours are there", "list the tours"), "I offer: {tours}."),
    Phrase("exhibits", ("what can i see", "list the exhibits"), "You can see: {exhibits}."),
    Phrase("start", ("start the tour", "give me a tour", "lets go"), "Follow me!", frozenset({IDLE}), "tour"),
    Phrase("goto", ("show me", "take me to", "go to"), "Let us go to {argument}.", _ALL, "exhibit"),
    Phrase("stop", ("stop", "wait", "halt"), "I stop here.", _AWAY, "stop"),
    Phrase(
        "next", ("next exhibit", "go on", "continue"), "On to the next one.", frozenset({EXHIBIT}), "next"
    ),
    Phrase("explain", ("tell me more", "what is this"), "{summary}", _AT),
    Phrase("repeat", ("say that again", "repeat please"), "{last}"),
    Phrase(
        "end",
        ("end the tour", "that is enough"),
        "Thank you for the visit!",
        frozenset({TOUR, EXHIBIT}),
        "stop",
    ),
    Phrase("thanks", ("thank you", "thanks"), "You are welcome."),
    Phrase("bye", ("goodbye", "bye"), "Goodbye, enjoy {site}!"),
    Phrase("web", ("who is watching", "are people watching"), "Visitors on the web see what I see."),
)


def _normal(text: str) -> str:
    return " ".join(re.sub(r"[^a-z0-9 ]", " ", text.lower().replace("'", "")).split())


@dataclass
class PhraseBook:
    """Understands phrases in the active context and composes the answers."""

    robot: str = "Lefkos"
    site: str = "the museum"
    tours: Sequence[str] = ()
    exhibits: dict[str, str] = field(default_factory=dict)
    phrases: tuple[Phrase, ...] = PHRASES
    threshold: float = 0.75
    context: str = IDLE
    last: str = "I said nothing yet."

    def active(self) -> list[Phrase]:
        return [p for p in self.phrases if self.context in p.contexts]

    def understand(self, text: str, summary: str = "") -> Reply | None:
        """The reply to ``text`` in the current context, or None when nothing matches well."""
        heard = _normal(text)
        if not heard:
            return None
        best: tuple[float, Phrase, str | None] | None = None
        for phrase in self.active():
            for said in phrase.says:
                argument = None
                candidate = heard
                if phrase.action == "exhibit":
                    if not heard.startswith(said + " "):
                        continue
                    argument = self._exhibit(heard[len(said) + 1 :])
                    if argument is None:
                        continue
                    candidate = said
                score = difflib.SequenceMatcher(None, candidate, said).ratio()
                if best is None or score > best[0]:
                    best = (score, phrase, argument)
        if best is None or best[0] < self.threshold:
            return None
        _, phrase, argument = best
        name = self.exhibits.get(argument, argument) if argument else ""
        text_out = phrase.answer.format(
            robot=self.robot,
            site=self.site,
            time=time.strftime("%H:%M"),
            tours=", ".join(self.tours) or "no tours yet",
            exhibits=", ".join(self.exhibits.values()) or "nothing yet",
            argument=name,
            summary=summary or "This exhibit has no description yet.",
            last=self.last,
        )
        if phrase.intent != "repeat":
            self.last = text_out
        return Reply(phrase.intent, text_out, phrase.action, argument, self.context)

    def _exhibit(self, words: str) -> str | None:
        """The exhibit slug whose name (or slug) sounds most like ``words``."""
        names = {_normal(name): slug for slug, name in self.exhibits.items()}
        names.update({_normal(slug): slug for slug in self.exhibits})
        match = difflib.get_close_matches(words.removeprefix("the "), list(names), n=1, cutoff=0.6)
        return names[match[0]] if match else None

    def switch(self, context: str) -> None:
        if context not in CONTEXTS:
            raise ValueError(f"unknown phrase context {context!r}; one of {CONTEXTS}")
        self.context = context
