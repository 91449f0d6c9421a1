"""The paper's own numbers: Table 1's frame rates and the overheads they imply."""

PAPER_DEVICE = "GeForce 6800 (256 MB; printed \"FX 6800\"), Pentium 4 3 GHz, 256³ volumes, OpenGL fragment programs"
"""Where Table 1 was measured (note 004 §3.1)."""

PAPER_SIZES = (512, 1024)
"""Table 1's viewports (square, pixels)."""

TABLE1 = {
    # the paper's row: (fps 512² no lens, 512² lens, 1024² no lens, 1024² lens)
    "seismic": (60.0, 58.3, 53.0, 49.1),
    "skull": (30.1, 24.0, 19.0, 14.7),
    "foot": (29.7, 25.3, 14.8, 9.7),
}
"""Table 1 verbatim (note 004 §3.3): frames per second, 256³ data sets, lens shapes and appearances not stated."""


def paper_fps(row, image, lens):
    """The paper's frame rate of ``row`` at viewport ``image`` (512 or 1024) with or without the lens."""
    if row not in TABLE1:
        raise KeyError(f"no row {row!r} in Table 1 (rows: {', '.join(TABLE1)})")
    if image not in PAPER_SIZES:
        raise KeyError(f"Table 1 has no {image}² viewport (viewports: {', '.join(map(str, PAPER_SIZES))})")
    return TABLE1[row][2 * PAPER_SIZES.index(image) + bool(lens)]


def paper_time_ratio(row, image):
    """Frame time with the lens over frame time without it: the paper's fps without over fps with."""
    return paper_fps(row, image, False) / paper_fps(row, image, True)


def paper_drop(row, image):
    """The paper's lens overhead as its fps drop, ``1 − fps_lens / fps_no_lens`` (note 004 §3.4)."""
    return 1.0 - paper_fps(row, image, True) / paper_fps(row, image, False)


def derived_table():
    """Note 004 §3.4 from Table 1: frame times, their difference, the fps drop and the time ratio per viewport."""
    rows = []
    for row in TABLE1:
        out = {"data set": row}
        for image in PAPER_SIZES:
            off, on = 1e3 / paper_fps(row, image, False), 1e3 / paper_fps(row, image, True)
            out |= {f"{image}² no lens (ms)": round(off, 2), f"{image}² lens (ms)": round(on, 2),
                    f"{image}² Δ (ms)": round(on - off, 2),
                    f"{image}² fps drop (%)": round(100 * paper_drop(row, image), 1),
                    f"{image}² time ratio": round(paper_time_ratio(row, image), 3)}
        rows.append(out)
    return rows
