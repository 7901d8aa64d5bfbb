"""``python -m ocdsl.report.reproduce``."""
import sys

from ocdsl.report.reproduce.cli import main


sys.exit(main())
