from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tourbot.web.speech import Speaker, SpeechConfig, SpeechError


@pytest.mark.skipif(shutil.which("espeak-ng") is None, reason="espeak-ng is not installed (CI installs it)")
def test_text_becomes_a_cached_wav_file(tmp_path: Path) -> None:
    speaker = Speaker(tmp_path)
    path = speaker.say("Welcome to the museum.")
    assert path is not None
    data = path.read_bytes()
    assert data[:4] == b"RIFF"
    assert data[8:12] == b"WAVE"
    assert len(data) > 10_000  # about a second of speech
    stamp = path.stat().st_mtime_ns
    assert speaker.say("Welcome  to the museum.") == path  # same words: the cached file
    assert path.stat().st_mtime_ns == stamp
    assert speaker.say("-v nonsense") is not None  # a leading dash is spoken, not an option


def test_without_espeak_there_is_no_audio_but_no_error(tmp_path: Path) -> None:
    speaker = Speaker(tmp_path, SpeechConfig(program="no-such-speech-program"))
    assert not speaker.available
    assert speaker.say("Hello") is None


def test_empty_or_long_text_is_refused(tmp_path: Path) -> None:
    speaker = Speaker(tmp_path, SpeechConfig(max_characters=10))
    with pytest.raises(SpeechError, match="nothing"):
        speaker.say("  ")
    with pytest.raises(SpeechError, match="at most 10"):
        speaker.say("far too long to say")
