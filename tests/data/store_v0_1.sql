-- A store written by fuelid 0.1 (schema 1), dumped with sqlite3's iterdump() for the upgrade test
-- (tests/integration/test_store_schema.py). Written at commit 2974128e3925f2a9107eb15526dce58266187674
-- (branch h-plcstore before the schema module) by
--     PYTHONPATH=$PWD/src python make_store_v0_1.py > tests/data/store_v0_1.sql
-- with this script (kept here so that the fixture can be written again):
--
-- """Write a small store with today's code and dump it as SQL (tests/data/store_v0_1.sql)."""
-- import math
-- import sqlite3
-- import sys
-- import tempfile
-- from pathlib import Path
--
-- from fuelid.store import Event, OnlineHistory, Sample, SQLiteStore, tag_map_hash
--
-- T0 = 1_700_000_000.0
-- db = Path(tempfile.mkdtemp()) / "loop.db"
-- site = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}
-- with SQLiteStore(db, period_s=0.02, **site) as store:
--     store.append(
--         [
--             Sample(T0 + 0.00, 0, 2.0, 40.0, 40.0, 21.5, 1, 0),
--             Sample(T0 + 0.02, 1, 2.1, 40.25, 40.0, 21.5, 1, 0),
--             Sample(T0 + 0.04, 2, 2.2, math.nan, 40.0, math.nan, None, 3),
--             Sample(T0 + 0.10, 5, 2.3, 41.5, 42.0, 21.625, 0, 1),
--             Sample(T0 + 0.12, 6, 2.3, 41.75, 42.0, 21.625, 0, 2),
--             Sample(T0 + 5.00, None, 1.5, 30.0, math.nan, 22.0, None, 0),
--         ],
--         [
--             Event(T0, "link_up", "connected to 127.0.0.1:5020"),
--             Event(T0 + 0.10, "gap", "3 samples lost"),
--             Event(T0 + 0.10, "gain_change", "Kc 0.05 -> 0.06"),
--         ],
--     )
--     with OnlineHistory(store) as history:
--         history.add_window(
--             t_from=T0, t_to=T0 + 600.0, accepted=True, reason="all gates passed",
--             T_fuel=21.5, u_mean=2.25, detail={"fit": 91.5, "gates": {"excitation": True}},
--             model={"kind": "FOPDT", "K": 12.5, "T": 0.42, "L": 0.08}, time=T0 + 601.0,
--         )
--         history.add_window(
--             t_from=T0 + 300.0, t_to=T0 + 900.0, accepted=False,
--             reason="too little excitation", T_fuel=math.nan, u_mean=None,
--             detail={"fit": None}, time=T0 + 901.0,
--         )
--         pid = history.add_proposal(
--             model_id=1, old={"Kc": 0.05, "Ti": 1.2}, new={"Kc": 0.06, "Ti": 1.1},
--             detail={"rule": "simc"}, time=T0 + 902.0, why="drift of K",
--         )
--         history.set_proposal_status(pid, "approved", who="operator", why="looks fine",
--                                     time=T0 + 903.0)
--         wid = history.begin_write(kind="proposal", kc=0.06, ti=1.1, apply_seq=1,
--                                   who="operator", why="approved", proposal_id=pid,
--                                   time=T0 + 904.0)
--         history.finish_write(wid, "verified", {"echo": {"Kc": 0.06, "Ti": 1.1}},
--                              time=T0 + 904.5)
--         history.set_state("last_known_good", {"Kc": 0.06, "Ti": 1.1})
-- con = sqlite3.connect(db)
-- sys.stdout.write("\n".join(con.iterdump()) + "\n")
-- # iterdump() leaves out the file's PRAGMAs: write the two that mark a fuelid store
-- for pragma in ("application_id", "user_version"):
--     sys.stdout.write(f"PRAGMA {pragma}={con.execute(f'PRAGMA {pragma}').fetchone()[0]};\n")
-- con.close()
--
BEGIN TRANSACTION;
CREATE TABLE events(time REAL NOT NULL, kind TEXT NOT NULL, detail TEXT NOT NULL) STRICT;
INSERT INTO "events" VALUES(1700000000.0,'link_up','connected to 127.0.0.1:5020');
INSERT INTO "events" VALUES(1700000000.1,'gap','3 samples lost');
INSERT INTO "events" VALUES(1700000000.1,'gain_change','Kc 0.05 -> 0.06');
CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL) STRICT;
INSERT INTO "meta" VALUES('schema_version','1');
INSERT INTO "meta" VALUES('site_name','tunnel 2 fuel loop');
INSERT INTO "meta" VALUES('tag_map_hash','3fe2cb6a377006e4c6201b2f39d9c547586e65acc8a8e0d6f7470dda9d23f8c2');
INSERT INTO "meta" VALUES('created','1795751311.57874');
INSERT INTO "meta" VALUES('period_s','0.02');
CREATE TABLE models(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL, t_to REAL, T_fuel REAL,
    model TEXT NOT NULL
) STRICT;
INSERT INTO "models" VALUES(1,1700000601.0,1700000000.0,1700000600.0,21.5,'{"kind":"FOPDT","K":12.5,"T":0.42,"L":0.08}');
CREATE TABLE online_state(
    key TEXT PRIMARY KEY, value TEXT NOT NULL, time REAL NOT NULL
) STRICT;
INSERT INTO "online_state" VALUES('last_known_good','{"Kc":0.06,"Ti":1.1}',1.79575131158460545542e+09);
CREATE TABLE proposals(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, model_id INTEGER REFERENCES models(id),
    kc REAL, ti REAL, status TEXT NOT NULL, detail TEXT NOT NULL
) STRICT;
INSERT INTO "proposals" VALUES(1,1700000902.0,1,0.06,1.1,'approved','{"old":{"Kc":0.05,"Ti":1.2},"new":{"Kc":0.06,"Ti":1.1},"detail":{"rule":"simc"},"history":[{"time":1700000902.0,"status":"pending","who":"online","why":"drift of K"},{"time":1700000903.0,"status":"approved","who":"operator","why":"looks fine"}]}');
CREATE TABLE samples(
    time REAL NOT NULL,
    seq INTEGER,
    u REAL,
    y REAL,
    setpoint REAL,
    fuel_temperature REAL,
    mode INTEGER,
    quality INTEGER NOT NULL CHECK (quality BETWEEN 0 AND 3)
) STRICT;
INSERT INTO "samples" VALUES(1700000000.0,0,2.0,40.0,40.0,21.5,1,0);
INSERT INTO "samples" VALUES(1700000000.02,1,2.1,40.25,40.0,21.5,1,0);
INSERT INTO "samples" VALUES(1700000000.04,2,2.2,NULL,40.0,NULL,NULL,3);
INSERT INTO "samples" VALUES(1700000000.1,5,2.3,41.5,42.0,21.625,0,1);
INSERT INTO "samples" VALUES(1700000000.12,6,2.3,41.75,42.0,21.625,0,2);
INSERT INTO "samples" VALUES(1700000005.0,NULL,1.5,30.0,NULL,22.0,NULL,0);
CREATE TABLE windows(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL NOT NULL, t_to REAL NOT NULL,
    accepted INTEGER NOT NULL CHECK (accepted IN (0, 1)), reason TEXT NOT NULL,
    T_fuel REAL, u_mean REAL, model_id INTEGER REFERENCES models(id), detail TEXT NOT NULL
) STRICT;
INSERT INTO "windows" VALUES(1,1700000601.0,1700000000.0,1700000600.0,1,'all gates passed',21.5,2.25,1,'{"fit":91.5,"gates":{"excitation":true}}');
INSERT INTO "windows" VALUES(2,1700000901.0,1700000300.0,1700000900.0,0,'too little excitation',NULL,NULL,NULL,'{"fit":null}');
CREATE TABLE writes(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, proposal_id INTEGER REFERENCES proposals(id),
    kind TEXT NOT NULL, kc REAL NOT NULL, ti REAL NOT NULL, apply_seq INTEGER NOT NULL UNIQUE,
    status TEXT NOT NULL, who TEXT NOT NULL, why TEXT NOT NULL, detail TEXT NOT NULL,
    finished REAL
) STRICT;
INSERT INTO "writes" VALUES(1,1700000904.0,1,'proposal',0.06,1.1,1,'verified','operator','approved','{"echo":{"Kc":0.06,"Ti":1.1}}',1700000904.5);
CREATE UNIQUE INDEX samples_seq ON samples(seq) WHERE seq IS NOT NULL;
CREATE UNIQUE INDEX samples_time_noseq ON samples(time) WHERE seq IS NULL;
CREATE INDEX samples_time ON samples(time);
CREATE INDEX events_time ON events(time);
CREATE INDEX windows_t_to ON windows(t_to);
CREATE INDEX windows_model ON windows(model_id) WHERE model_id IS NOT NULL;
COMMIT;
PRAGMA application_id=1179994436;
PRAGMA user_version=1;
