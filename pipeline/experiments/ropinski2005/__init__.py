"""Ropinski, Steinicke & Hinrichs 2005: lens volumes, regions of interest with their own appearance in GPU ray casting.

The paper's guide is ``../shared/papers/notes/004.md`` (§4.2 lists the experiments E1–E9, §5 the
stand-ins). Its only measurement is Table 1's frame rates without and with the lens on a 2005 GPU;
those do not transfer to another device, so the speed claims compare runs timed together on one machine
(the lens's overhead, a ratio), and the counts the caster keeps (samples per region, rays through the
lens) say what any device has to do.

Its experiments are :data:`EXPERIMENTS`, one module each; :mod:`.scenes` (the lens scenes), :mod:`.methods`
(the lens methods), :mod:`.pages` and :mod:`.tables` (the paper's numbers) hold what they share.
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
