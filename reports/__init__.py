"""Report layer of volbench: image I/O (:mod:`reports.imageio`), accuracy metrics
(:mod:`reports.metrics`), SVG figures (:mod:`reports.plots`) and the HTML report."""
