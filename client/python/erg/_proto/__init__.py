# SPDX-License-Identifier: Apache-2.0
"""The erg.v1 messages and gRPC stubs, generated from proto/erg/v1 by
client/python/gen_stubs.py (the ctest python.stubs checks they are current)."""
