"""o3dheat's built-in filters, one module each, registered in the entry-point group ``o3dheat.filters`` like any plugin.

They follow the protocol of :mod:`o3dheat.pipelines.filters` and are written with the public filter
SDK :mod:`o3dheat.pipelines.site`, importing only public o3dheat modules.
"""
