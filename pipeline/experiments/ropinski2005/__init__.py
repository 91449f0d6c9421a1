"""Ropinski, Steinicke & Hinrichs 2005: lens volumes, regions of interest with their own appearance in GPU ray casting.

The paper's guide is ``../shared/papers/notes/004.md`` (§4.2 lists the experiments E1–E9, §5 the
stand-ins). Its only measurement is Table 1's frame rates without and with the lens on a 2005 GPU;
those do not transfer to another device, so the speed claims compare runs timed together on one machine
(the lens's overhead, a ratio), and the counts the caster keeps (samples per region, rays through the
lens) say what any device has to do.

* :mod:`.table1`: ``ropinski2005-table1`` (E1): every lens scene without and with its lens at two image
  sizes, the overheads beside the paper's;
* :mod:`.passes`: ``ropinski2005-passes`` (E2): the segments method's frame, pass by pass;
* :mod:`.samples`: ``ropinski2005-samples`` (E3): the samples with and without the lens, and per region;
* :mod:`.methods_compared`: ``ropinski2005-methods`` (E4): the segments method against the per-sample
  tests, the mask fetch, frag-depth and the fused loop, with and without an occluder (early-z);
* :mod:`.lens_size`: ``ropinski2005-size`` (E5): the overhead against the lens's coverage;
* :mod:`.appearances`: ``ropinski2005-appearance`` (E6): clip, transparency, iso and MIP lenses;
* :mod:`.correctness`: ``ropinski2005-correctness`` (E7): every lens method against the reference, and a
  lens showing the outside appearance against no lens;
* :mod:`.edges`: ``ropinski2005-edges`` (E8): lenses partly outside, in front, behind, enclosing the volume
  or the camera, grazing: holes and accuracy, the paper's hole in the stencil method;
* :mod:`.order`: ``ropinski2005-order`` (E9): region passes front to back against back to front;
* :mod:`.peers`: ``ropinski2005-peers``: the lens in VTK (label map, cropping, clipping planes) and in
  shear-warp's pre-classification beside the paper's method, by overhead and error;
* :mod:`.scenes`: the lens scenes (note 004 §5) and their controls; :mod:`.methods`: the lens methods as
  ``gl-raycast`` options and what the experiments share; :mod:`.pages`: what their pages share;
  :mod:`.tables`: the paper's numbers.
"""

from pipeline.experiments.kit.model import Paper
from pipeline.experiments.ropinski2005.appearances import Appearances
from pipeline.experiments.ropinski2005.correctness import Correctness
from pipeline.experiments.ropinski2005.edges import Edges
from pipeline.experiments.ropinski2005.lens_size import LensSize
from pipeline.experiments.ropinski2005.methods_compared import MethodsCompared
from pipeline.experiments.ropinski2005.order import Order
from pipeline.experiments.ropinski2005.passes import Passes
from pipeline.experiments.ropinski2005.peers import Peers
from pipeline.experiments.ropinski2005.samples import Samples
from pipeline.experiments.ropinski2005.table1 import Table1

EXPERIMENTS = (Table1, Passes, Samples, MethodsCompared, LensSize, Appearances, Correctness, Edges, Order, Peers)

PAPER = Paper("ropinski2005", "gl-raycast", needs="lens volumes (regions of interest) in the OpenGL ray caster",
              experiments=EXPERIMENTS)
"""What this paper needs and which experiments reproduce it (the registry reads it)."""
