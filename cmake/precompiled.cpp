// The translation unit that builds mosaicloc's shared precompiled header
// (mosaicloc_add_precompiled_headers in MosaiclocModule.cmake); it has no code of its own.
