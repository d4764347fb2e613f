"""Reports of the discrepancy analysis: the JSON of docs/MODEL.md section 6 and a page
(Markdown and its HTML twin, analysis.report.pages) with figures (matplotlib, Agg backend)."""

from analysis.report.discrepancy import write_analysis_json, write_report

__all__ = ["write_analysis_json", "write_report"]
