"""The CottonSim paper's Tables 2 and 3 beside our evaluation results (markdown rows).

Why: docs/perception.md compares the networks with the paper on the same
definitions. The paper's Table 2 holds its *training* results (the metrics
on its validation split during training), Table 3 its *testing* results; all
values are percentages at IoU 0.5 (P, R, mAP50). Our numbers come from the
JSON written by ``evaluate`` (see :mod:`cottonsim_perception.evaluation.cli`).
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

#: table -> task -> class -> (precision %, recall %, mAP50 %)
PAPER_TABLES: Dict[str, Dict[str, Dict[str, Tuple[float, float, float]]]] = {
    "table2": {"seg": {"sky": (99.0, 94.1, 95.0), "ground": (99.0, 94.1, 95.3),
                       "cotton plants": (100.0, 96.2, 98.4), "all": (99.3, 94.8, 96.2)},
               "det": {"cotton boll": (92.9, 85.6, 92.6), "all": (92.9, 85.6, 92.6)}},
    "table3": {"seg": {"sky": (99.1, 66.7, 66.9), "ground": (99.7, 100.0, 99.5),
                       "cotton plants": (82.1, 100.0, 86.2), "all": (93.0, 88.9, 85.2)},
               "det": {"cotton boll": (94.8, 87.2, 92.7), "all": (94.8, 87.2, 92.7)}},
}


def _pct(v: Optional[float]) -> str:
    return "-" if v is None else f"{100.0 * v:.1f}"


def comparison_rows(result: Dict[str, object], table: str, label: str = "") -> List[str]:
    """Markdown rows '| label | class | images | instances | P | R | mAP50 | mAP50-95 | paper P / R / mAP50 |'.

    result: one split's dict from the evaluate JSON (``out["splits"][name]``);
    the mask metrics are used for 'seg', the box metrics for 'det'.
    table: 'table2' or 'table3' (or '' for no paper column). Raises ValueError
    for an unknown table or a result without the needed metrics.
    """
    if table and table not in PAPER_TABLES:
        raise ValueError(f"table must be one of {sorted(PAPER_TABLES)} or '', got {table!r}")
    task = result.get("task")
    kind = "mask" if task == "seg" else "box"
    if task not in ("seg", "det") or kind not in result:
        raise ValueError(f"result has no '{kind}' metrics for task {task!r}")
    paper = PAPER_TABLES[table][task] if table else {}
    rows = []
    for row in result[kind]["rows"]:
        ref = paper.get(str(row["class"]))
        ref_text = " / ".join(f"{v:.1f}" for v in ref) if ref else "-"
        rows.append(f"| {label} | {row['class']} | {row['images']} | {row['instances']} | {_pct(row['p'])} | "
                    f"{_pct(row['r'])} | {_pct(row['map50'])} | {_pct(row['map50_95'])} | {ref_text} |")
    return rows


HEADER: Sequence[str] = (
    "| data | class | images | instances | P | R | mAP50 | mAP50-95 | paper P / R / mAP50 |",
    "|---|---|---|---|---|---|---|---|---|",
)
