-- Issue 75: the targets whose mean series gave a point's filtered forecast (not declared as a
-- block, they move together), one row per point and epoch where the forecast was pooled, so
-- that the point's page can say so.
CREATE TABLE pooled_forecasts (
    site_id     TEXT NOT NULL,
    epoch_id    BIGINT NOT NULL,
    point       TEXT NOT NULL,
    pooled_with TEXT NOT NULL,
    PRIMARY KEY (site_id, point, epoch_id),
    FOREIGN KEY (site_id, epoch_id) REFERENCES epochs (site_id, id)
);
