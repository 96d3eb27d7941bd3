"""Readers and writers of models and parameter files.

Where a model comes from and where results go: Menagerie and MJCF sources
(:mod:`~poekin.io.sources`), :func:`poekin.load` (:mod:`~poekin.io.loading`), the MuJoCo and
URDF importers, parameter files and the named parameter sets (:mod:`~poekin.io.paramfile`,
:mod:`~poekin.io.params`, :mod:`~poekin.io.ur_kinematics`), and the array, CSV and figure
files of the CLI (:mod:`~poekin.io.fileio`).
"""
