"""tourbot: software for tour-guide robots in crowded exhibitions.

Parts (see ``docs/architecture.md``): ``geometry``, ``records``, ``io``, ``maps``,
``localization``, ``people``, ``objects``, ``mapping``, ``ceiling``, ``sim``, ``navigation``,
``runtime``, ``web`` and ``bench``.
"""

__version__ = "0.1.0"
__all__ = ["__version__"]
