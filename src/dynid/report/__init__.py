"""Reports: tables for the terminal, validation figures, a self-contained HTML file."""

from .figures import residual_histograms, validation_figure
from .html import Section, render_html
from .tables import parameter_table, validation_table

__all__ = ["Section", "parameter_table", "render_html", "residual_histograms", "validation_figure",
           "validation_table"]
