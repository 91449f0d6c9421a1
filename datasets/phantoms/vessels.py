"""Vessel trees and the aneurysm phantom (notes 000 and 001, "Philips aneurism").

A tree is grown recursively: each branch is a gently curving polyline of tapered capsules, split
at its end into two children whose radii follow Murray's law, ``r³ = r₁³ + r₂³``: the larger child
takes a random share λ of the flow (``r₁ = r λ^⅓``) and turns less, the smaller one branches off at
a wider angle, so calibres taper from trunk to twig as in an angiogram. The topology is drawn
from the generator alone, never from ``size``, so a seed gives the same tree at every resolution.
"""

from dataclasses import dataclass

import numpy as np

from datasets import noise
from datasets.shapes import Canvas, Capsule, Grid, Sphere, frame, rotation
from core.volume import Volume

V = 1 / 256


@dataclass
class Branch:
    """One branch: ``points`` (k, 3) along its centre line and the radius at each point."""

    points: np.ndarray
    radii: np.ndarray
    generation: int

    def capsules(self):
        return [Capsule(self.points[i], self.points[i + 1], self.radii[i], self.radii[i + 1])
                for i in range(len(self.points) - 1)]


def _perpendicular(rng, direction):
    """A random unit vector perpendicular to ``direction``."""
    basis = frame(direction)
    angle = rng.uniform(0, 2 * np.pi)
    return np.cos(angle) * basis[:, 0] + np.sin(angle) * basis[:, 1]


def grow_tree(rng, start, direction, *, radius, length, generations, segments=6, wiggle=10.0,
              spread=(25.0, 45.0), taper=0.92, split=(0.5, 0.8), length_ratio=0.8, limit=0.55):
    """Grow a branching tree of :class:`Branch` objects.

    Parameters
    ----------
    rng : numpy.random.Generator
    start, direction : array_like
        Root point and initial direction (normalised coordinates).
    radius, length : float
        Root radius and length. A branch narrows to ``taper`` times its start radius; its
        children's radii follow Murray's law and their lengths scale by ``length_ratio`` times
        their share of the parent's radius (±20 % jitter).
    generations : int
        Levels of bifurcation below the root.
    segments : int
        Capsules per branch.
    wiggle : float
        Standard deviation, degrees, of the direction change between segments.
    spread : (float, float)
        Range of the angle, degrees, between the smaller child and its parent's direction; the
        larger child turns by that angle times ``(1 − λ)/λ``.
    taper : float
        End radius over start radius of one branch.
    split : (float, float)
        Range of λ, the larger child's share of the flow (0.5: a symmetric fork).
    limit : float
        A branch stops where it leaves the box ``[-limit, limit]³``.

    Returns
    -------
    list of Branch
    """
    branches = []
    stack = [(np.asarray(start, float), np.asarray(direction, float), radius, length, 0)]
    while stack:
        point, direction, r, length_here, generation = stack.pop()
        direction = direction / np.linalg.norm(direction)
        points, step = [point], length_here / segments
        for _ in range(segments):
            direction = rotation(_perpendicular(rng, direction), rng.normal(0, wiggle)) @ direction
            points.append(points[-1] + step * direction)
            if np.any(np.abs(points[-1]) > limit):
                break
        points = np.array(points)
        end_radius = r * taper
        radii = np.linspace(r, end_radius, len(points))
        branches.append(Branch(points, radii, generation))
        if generation < generations and len(points) == segments + 1:
            axis = _perpendicular(rng, direction)
            share = rng.uniform(*split)
            angle = rng.uniform(*spread)
            for fraction, turn in ((share, angle * (1 - share) / share), (1 - share, -angle)):
                child = rotation(axis, turn) @ direction
                child_r = end_radius * fraction ** (1 / 3)
                stack.append((points[-1], child, child_r,
                              length_here * length_ratio * (child_r / end_radius) * rng.uniform(0.8, 1.2),
                              generation + 1))
    return branches


def paint_tree(canvas, branches, values, *, label=None):
    """Paint each branch (the union of its capsules) with its value from ``values``."""
    grid = canvas.grid
    for branch, value in zip(branches, values):
        canvas.paint(grid.union(branch.capsules()), value, label=label)


def aneurysm(size, seed):
    """3-D rotational angiography of head arteries with a saccular aneurysm (notes 000, 001).

    Three arterial trees (two carotids, one basilar) enter through the bottom face and branch
    seven times by Murray's law, radius 9 voxels (at 256) at the roots down to about 1.5 in
    the smallest twigs, intensity 205–250 per branch, over a near-zero background (≈4 ± 2.5). A
    saccular aneurysm (a sphere of radius 15 voxels on a neck) sits on the outside of the first
    bifurcation of a first-generation branch. Vessels fill 1–3 % of the volume, so most 8³
    blocks are empty.
    """
    rng = np.random.default_rng(seed)
    grid = Grid.for_aspect(size)
    canvas = Canvas(grid, background=4.0)
    topology = noise.fork(rng)
    roots = (((-0.17, -0.08, -0.53), (0.15, -0.05, 1.0)),
             ((0.17, -0.08, -0.53), (-0.15, -0.05, 1.0)),
             ((0.0, 0.16, -0.53), (0.0, -0.25, 1.0)))
    branches = []
    for start, direction in roots:
        branches += grow_tree(topology, start, direction, radius=9 * V, length=0.34, generations=7,
                              taper=0.92, length_ratio=1.0)
    values = topology.uniform(205, 250, len(branches))
    paint_tree(canvas, branches, values)
    parent = next(b for b in branches if b.generation == 1 and len(b.points) > 2)
    tip = parent.points[-1]
    heading = (tip - parent.points[-2]) / np.linalg.norm(tip - parent.points[-2])
    canvas.paint(Capsule(tip, tip + heading * 8 * V, parent.radii[-1] * 1.3, 8 * V), 235)   # neck
    canvas.paint(Sphere(tip + heading * 19 * V, 15 * V), 235)
    noise.add_gaussian(canvas.data, noise.fork(rng), 2.5)
    return Volume(canvas.to_uint8(), name="aneurysm")
