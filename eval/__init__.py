"""Evaluation: episodes of any policy on the study's cases, statistics, figures, reports."""
