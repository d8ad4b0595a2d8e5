"""The static web site of `mlct export-web`: the model run in the browser (export.py), the npm
files it vendors (vendor.py), its page and modules (static/)."""

from mlct.serve.site.export import export_site, load_site_reference, site_size

__all__ = ["export_site", "load_site_reference", "site_size"]
