"""The vision ablation table: both modes side by side per seed, '-' where a report lacks a figure."""
from cottonsim_navigation.evaluation.vision_ablation import ablation_figures, ablation_markdown, ablation_table

ON = {"cr_percent": 100.0, "ae_m": 0.0512, "cross_track_mean_m": 0.0123, "real_time_factor": 0.61,
      "navigator": {"halts": 12, "halt_time_s": 24.0}, "vision_no_estimate_fraction": 0.05,
      "vision_boll_verdicts_per_sim_s": 9.5}
OFF = {"cr_percent": 100.0, "ae_m": 0.0534, "cross_track_mean_m": 0.0160, "real_time_factor": 4.2, "halts": 0,
       "halt_time_s": 0.0}


def _row(lines, label):
    return next(l for l in lines if l.startswith(f"| {label} |"))


def test_table_puts_both_modes_side_by_side_with_units_scaled():
    lines = ablation_table(ON, OFF)
    assert lines[0].startswith("| figure | with vision")
    assert _row(lines, "AE [m]") == "| AE [m] | 0.051 | 0.053 |"
    assert _row(lines, "in-row cross-track, mean [cm]") == "| in-row cross-track, mean [cm] | 1.23 | 1.60 |"
    assert _row(lines, "halts at bolls") == "| halts at bolls | 12 | 0 |"          # from the navigator's state
    assert _row(lines, "frames with no estimate [%]") == "| frames with no estimate [%] | 5.0 | - |"
    assert _row(lines, "RMSE [m]") == "| RMSE [m] | - | - |"


def test_figures_and_markdown_per_seed_only_where_both_modes_have_a_report():
    figs = ablation_figures(ON, OFF)
    assert figs["real_time_factor"] == {"vision": 0.61, "no_vision": 4.2}
    on = {"runs": [{"seed": 0, "report": ON}, {"seed": 1, "report": ON}]}
    off = {"runs": [{"seed": 0, "report": OFF}, {"seed": 1, "report": None}]}
    md = ablation_markdown(on, off)
    assert md[0] == "Seed 0:" and not any(l == "Seed 1:" for l in md)
    assert ablation_markdown(on, None) == []


def test_section_reads_both_route_folders_and_needs_a_shared_seed(tmp_path):
    import json
    from cottonsim_navigation.evaluation.vision_ablation import ablation_section
    assert ablation_section(str(tmp_path), "gps_route") == []
    for name, vision, report in (("gps_route", True, ON), ("gps_route_no_vision", False, OFF)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "summary.json").write_text(json.dumps(
            {"vision": vision, "machine": "test box", "runs": [{"seed": 0, "report": report}]}))
    lines = ablation_section(str(tmp_path), "gps_route")
    assert lines[0] == "### Vision ablation: gps_route"
    assert "--vision both" in lines[2] and "test box" in lines[2]
    assert "| AE [m] | 0.051 | 0.053 |" in lines
