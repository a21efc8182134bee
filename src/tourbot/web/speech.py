"""The robot's voice (Burgard et al., section 6.2): "The text to be spoken is converted into audio
files that are played back." Text goes through espeak-ng into WAV files, cached by content, which
the on-board page plays.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from tourbot.errors import TourbotError

__all__ = ["Speaker", "SpeechConfig", "SpeechError"]


class SpeechError(TourbotError):
    """Text that cannot be spoken."""


@dataclass(frozen=True)
class SpeechConfig:
    voice: str = "en"
    words_per_minute: int = 150
    max_characters: int = 600
    program: str = "espeak-ng"


class Speaker:
    """Text to WAV files in ``folder`` (one per distinct text and voice, made once)."""

    def __init__(self, folder: Path, config: SpeechConfig | None = None) -> None:
        self.folder = folder
        self.config = config or SpeechConfig()
        self.program = shutil.which(self.config.program)

    @property
    def available(self) -> bool:
        return self.program is not None

    def name_for(self, text: str) -> str:
        key = f"{self.config.voice}|{self.config.words_per_minute}|{text}"
        return hashlib.sha256(key.encode()).hexdigest()[:24] + ".wav"

    def say(self, text: str) -> Path | None:
        """The WAV file speaking ``text``; None when espeak-ng is not installed."""
        text = " ".join(text.split())
        if not text:
            raise SpeechError("nothing to say")
        if len(text) > self.config.max_characters:
            raise SpeechError(f"{len(text)} characters to say, at most {self.config.max_characters}")
        if self.program is None:
            return None
        path = self.folder / self.name_for(text)
        if path.exists():
            return path
        self.folder.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(".part")
        command = [self.program, "-v", self.config.voice, "-s", str(self.config.words_per_minute)]
        try:
            # "--" ends the options: a text starting with "-" is spoken, not parsed.
            subprocess.run(
                [*command, "-w", str(partial), "--", text], check=True, capture_output=True, timeout=30
            )
        except (subprocess.SubprocessError, OSError) as exc:
            partial.unlink(missing_ok=True)
            raise SpeechError(f"espeak-ng failed: {exc}") from exc
        partial.replace(path)
        return path
