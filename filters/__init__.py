"""o3dheat's built-in filters, registered in the entry-point group ``o3dheat.filters`` like any
third-party plugin (see :mod:`o3dheat.pipelines.filters`). One module per filter."""
