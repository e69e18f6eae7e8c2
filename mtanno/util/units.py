"""The units every stage shares (docs/formats.md): the analysis rate.

Frames at :data:`ANALYSIS_FPS` are the frames of feature files, templates, truth and
annotation tables (1-based inclusive in every file, 0-based inside the code); a motion
file's own frames are *native* frames.
"""

__all__ = ["ANALYSIS_FPS"]

#: The analysis frame rate (Hz): features are reduced to it ([MR06] §2), and every table's
#: frames count at it unless a column says ``native``.
ANALYSIS_FPS = 30.0
