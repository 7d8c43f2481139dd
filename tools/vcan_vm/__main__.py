import sys

from tools.vcan_vm.harness import main

sys.exit(main())
