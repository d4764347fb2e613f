"""Discrepancy analysis: where the baseline model fails on a record, which named cause
explains it, and how much the extended model gains (docs/MODEL.md section 6)."""

from analysis.discrepancy.analyze import Analysis, AnalysisError, analyze_record
from analysis.discrepancy.candidates import candidates_for, excluded_for
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy

__all__ = ["DEFAULT_POLICY", "Analysis", "AnalysisError", "SelectionPolicy", "analyze_record",
           "candidates_for", "excluded_for"]
