"""Everything that draws: the figure spec (:mod:`.spec`), its matplotlib renderer for
every PNG (:mod:`.mpl`: the run's, the sweep's, the report's), the run's plots as specs
(:mod:`.plots`; a run draws them in its own process once its results are written) and
the zoomable results pages (:mod:`.pages`, built with bokeh's Python API).

It knows nothing of a run but the result it is handed: :mod:`glider_cosim.runner` uses it,
never the other way round.
"""
