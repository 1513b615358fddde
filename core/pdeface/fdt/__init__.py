"""Facial Deformation Tables (Obaid, Mukundan, Sagar, Billinghurst 2009) beside the PDE descriptors.

An expression as 16 muscle regions' quadratic ("rubber-sheet") transforms in
the pupil-normalised frame: :mod:`~pdeface.fdt.regions` (frame, regions),
:mod:`~pdeface.fdt.quadratic` (one region's transform), :mod:`~pdeface.fdt.table`
(the table, its generic mean ± σ and files), :mod:`~pdeface.fdt.deform` (fit
from faces, apply to a face model as a descriptor, classify); the ``pdeface fdt ...``
commands are :mod:`pdeface.cli.fdt`.
"""
