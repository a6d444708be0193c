"""``python -m graph_slam`` runs the CLI."""

from graph_slam.cli import main

main()
