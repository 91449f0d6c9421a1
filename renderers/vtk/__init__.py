"""VTK's volume mappers as peer backends: ``vtk-gpu`` (:mod:`.gpu`) and ``vtk-cpu`` (:mod:`.cpu`).

:mod:`.common` holds what they share (scene to VTK objects, the offscreen EGL window, float
readback, probe). Importing this package does not import VTK.
"""
