"""History probes: what fills the history slots of a clip when a model is scored, the one home of every probe.

A probe scores one model with its history replaced, to measure whether (and how) the model reads it
(docs/training.md). Each `Probe` names the dataset's history source (`ClipDataset`'s ``history_source``) and the
alignment it is read with:

- ``real``: the clip's own history (what the model was trained on);
- ``key``: copies of the key frame in every history slot (no history at all);
- ``warped_key``: the key frame warped out to each history frame's view and back by the alignment (the matched null
  of an aligned model: the alignment's blur without the history's content);
- ``reversed``: the clip's own history in reverse order;
- ``other_clip``: another clip's history frames;
- ``exact``: the real history aligned by the generator's exact homographies (``data.clip.align: true``) instead of
  the run's own alignment (ORB on the fly): what a perfect alignment would give.

A folder of frames or a video (`stamlane.data.datamodule.FramesDataModule`) has neither homographies nor other
clips: only ``real`` and ``key`` (`Probe.folder`). A run that does not align sees the same input with ``warped_key``
as with ``key`` (`Probe.unaligned_as`): it is predicted once, as ``key``.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "EXACT",
    "FOLDER_HISTORIES",
    "HISTORIES",
    "KEY",
    "OTHER_CLIP",
    "PROBES",
    "REAL",
    "REVERSED",
    "WARPED_KEY",
    "Probe",
]


@dataclass(frozen=True)
class Probe:
    """One way to fill a clip's history when scoring (see the module docstring).

    Attributes:
        name: the probe's name (``<split>@<name>`` in scores and prediction folders; ``real`` is the split alone).
        history: the dataset's history source (`HISTORIES`).
        exact: the history aligned by the generator's exact homographies (``data.clip.align: true``), whatever
            alignment the run was trained with.
        folder: available for a folder of frames or a video too.
        unaligned_as: the probe whose input this one equals for a run that does not align (scored as that one,
            predicted once), or None.
    """

    name: str
    history: str
    exact: bool = False
    folder: bool = False
    unaligned_as: str | None = None

    def __str__(self) -> str:
        return self.name

    @classmethod
    def of(cls, name: str | Probe) -> Probe:
        """The probe called ``name`` (a probe is itself).

        Raises:
            ValueError: no probe of that name, naming the known ones.
        """
        if isinstance(name, Probe):
            return name
        if name not in PROBES:
            raise ValueError(f"no history probe {name!r}; known: {', '.join(PROBES)}")
        return PROBES[name]

    def predicted_as(self, aligns: bool) -> Probe:
        """The probe whose predictions stand for this one on a run that aligns (``aligns``) or not."""
        return self if aligns or self.unaligned_as is None else PROBES[self.unaligned_as]


REAL = Probe("real", "real", folder=True)
KEY = Probe("key", "key", folder=True)
WARPED_KEY = Probe("warped_key", "warped_key", unaligned_as="key")
REVERSED = Probe("reversed", "reversed")
OTHER_CLIP = Probe("other_clip", "other_clip")
EXACT = Probe("exact", "real", exact=True)
PROBES = {p.name: p for p in (REAL, KEY, WARPED_KEY, REVERSED, OTHER_CLIP, EXACT)}
"""Every probe by its name."""
HISTORIES = tuple(p.history for p in PROBES.values() if not p.exact)
"""What fills a clip's history slots (`ClipDataset`'s and `ClipDataModule`'s ``history_source``)."""
FOLDER_HISTORIES = tuple(p.history for p in PROBES.values() if p.folder)
"""What fills the history slots of a folder's or a video's clips (`FramesDataModule`'s ``history_source``)."""
