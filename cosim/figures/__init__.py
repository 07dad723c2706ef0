"""Everything that draws: the figure spec (:mod:`.spec`), its Pillow rasterizer
(:mod:`.raster`, :mod:`.strokes`), the run's plots as specs (:mod:`.plots`), the drawing
process that draws them while a run runs (:mod:`.drawing`) and the zoomable results pages
(:mod:`.pages`, :mod:`.page_script`, :mod:`.figure_data`).

It knows nothing of a run but the result it is handed: :mod:`glider_cosim.runner` uses it,
never the other way round.
"""
