from __future__ import annotations

import pytest

from tourbot.web.phrases import CONTEXTS, PHRASES, PhraseBook


def book() -> PhraseBook:
    return PhraseBook(
        robot="Lefkos", site="FHW", tours=["Costumes"], exhibits={"chiton": "Chiton", "loom": "Loom"}
    )


def test_about_twenty_phrases_in_switchable_contexts() -> None:
    assert 18 <= len(PHRASES) <= 22  # the paper: "20 different phrases"
    assert {c for p in PHRASES for c in p.contexts} == set(CONTEXTS)


@pytest.mark.parametrize(
    ("said", "intent", "words"),
    [
        ("Who are you?", "who", "Lefkos"),
        ("where are you from", "origin", "FHW"),
        ("What time is it", "time", "It is"),
        ("how's the weather", "weather", "Indoors"),
        ("which tours are there", "tours", "Costumes"),
        ("hello", "hello", "Lefkos"),
    ],
)
def test_questions_about_robot_site_time_and_weather(said: str, intent: str, words: str) -> None:
    reply = book().understand(said)
    assert reply is not None
    assert reply.intent == intent
    assert words in reply.text


def test_small_recognition_errors_still_match_but_nonsense_does_not() -> None:
    assert book().understand("who ar you") is not None
    assert book().understand("purple elephants dance") is None
    assert book().understand("   ") is None


def test_contexts_decide_what_is_understood() -> None:
    b = book()
    assert b.understand("next exhibit") is None  # only at an exhibit
    reply = b.understand("give me a tour")
    assert reply is not None
    assert reply.action == "tour"
    b.switch("exhibit")
    assert b.understand("give me a tour") is None  # already touring
    nxt = b.understand("next exhibit")
    assert nxt is not None
    assert nxt.action == "next"
    explained = b.understand("tell me more", summary="Woven wool.")
    assert explained is not None
    assert explained.text == "Woven wool."
    with pytest.raises(ValueError, match="unknown phrase context"):
        b.switch("disco")


def test_go_to_an_exhibit_by_its_name() -> None:
    reply = book().understand("show me the loom")
    assert reply is not None
    assert (reply.action, reply.argument) == ("exhibit", "loom")
    assert "Loom" in reply.text
    assert book().understand("show me the spaceship") is None


def test_repeat_says_the_last_answer_again() -> None:
    b = book()
    first = b.understand("who are you")
    again = b.understand("say that again")
    assert first is not None
    assert again is not None
    assert again.text == first.text
