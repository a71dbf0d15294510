import sys

from boresight.cli.main import main

sys.exit(main())
