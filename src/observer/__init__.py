"""The observer: Butterworth pre-filter and nonlinear speed/glide-angle observer."""
